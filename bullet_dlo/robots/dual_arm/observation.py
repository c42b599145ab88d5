"""What is measured in the dual-arm scene: the two wrist F/T sensors and the per-step record.

The sensors are updated after every Bullet step (each samples at its own rate, see
:class:`~bullet_dlo.robots.sensors.WristSensor`); the record then stores, per step, the
sensor readings beside the model's ground truth (the cable's end forces and clamp torques,
grasp-frame and cable-end positions), the pairs the tests and the study compare.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from bullet_dlo.core.validate import ParameterError, check_positive
from bullet_dlo.robots.dual_arm.physics import END_NODE, DualArmPhysics
from bullet_dlo.robots.sensors import WristSensor


@dataclass
class DualArmRecord:
    """Per-step data, arms in the order (left, right): t [s] (n,); sensor wrenches in world
    [fx fy fz mx my mz] [N, N m] (n, 2, 6); the model's end forces [N] and clamp torques [N m]
    (n, 2, 3); grasp-frame and cable-end positions [m] (n, 2, 3)."""

    t: list = field(default_factory=list)
    wrench_world: list = field(default_factory=list)
    end_forces: list = field(default_factory=list)
    end_moments: list = field(default_factory=list)
    grasp_pos: list = field(default_factory=list)
    cable_end_pos: list = field(default_factory=list)

    def arrays(self) -> dict[str, np.ndarray]:
        """The columns as arrays, shapes as in the class docstring."""
        return {k: np.array(v) for k, v in self.__dict__.items()}


class DualArmObservation:
    """Wrist sensors on both arms (settings from ``physics.spec``) and, optionally, the per-step record.

    Build it right after the physics, before the first step: the sensors tare on the arms'
    last settle step, taken before the cable was attached (as users zero an ATI sensor in the
    grasp pose before grasping). A dataset capture or an environment with its own recording
    passes ``record=False`` and reads ``sensors[i].last`` (a :class:`~bullet_dlo.robots.sensors.Wrench`)
    from its own ``world.after_step`` hook.
    """

    def __init__(self, physics: DualArmPhysics, record: bool = True):
        if physics.world.steps:
            raise ParameterError("build the observation before the first step: its sensors tare on the unloaded arms")
        spec = physics.spec
        self.physics = physics
        self.sensors = [WristSensor(robot, spec.sensor_rate, spec.noise_std, spec.bias,
                                    rng=np.random.default_rng(spec.seed + k), reader=physics.reader, row=k)
                        for k, robot in enumerate(physics.robots)]
        for s in self.sensors:
            s.tare()
        self.record = DualArmRecord()
        world = physics.world
        world.after_physics.append(self._update_sensors)
        if record:
            world.after_step.append(self._record_step)

    def _update_sensors(self) -> None:
        world = self.physics.world
        for s in self.sensors:
            s.update(world.time, world.dt)

    def _record_step(self) -> None:
        r, cable = self.record, self.physics.cable
        r.t.append(self.physics.world.time)
        r.wrench_world.append([s.last.world() for s in self.sensors])
        r.end_forces.append(cable.end_forces())
        r.end_moments.append(cable.end_moments())
        r.grasp_pos.append(cable.holder_positions())
        r.cable_end_pos.append([cable.x[node].copy() for node in END_NODE])

    def window_mean(self, seconds: float = 0.5) -> dict[str, np.ndarray]:
        """Averages over the last ``seconds`` [s] of the record: sensor wrench in world (2, 6), end forces (2, 3)."""
        rec = self.record.arrays()
        if not len(rec["t"]):
            raise ParameterError("window_mean: nothing recorded yet (run the scene first)")
        sel = rec["t"] >= rec["t"][-1] - check_positive("window", seconds) + 1e-12
        return {"wrench_world": rec["wrench_world"][sel].mean(axis=0),
                "end_forces": rec["end_forces"][sel].mean(axis=0)}
