"""Two arms facing each other across a table, holding the two ends of a cable, in three parts.

In the manner of dm_control:

* :mod:`.physics`: :class:`DualArmPhysics`, the world, the two arms, the cable and the grasp
  coupling (held ends follow the grasp frames; the cable's end force and clamp torque act on
  the grippers, so they flow through the arms into the wrist sensors): everything to step.
* :mod:`.task`: :class:`DualArmTask`, an episode of the grasp study: grasp and release,
  Cartesian gripper moves with minimum-jerk profiles tracked by IK.
* :mod:`.observation`: :class:`DualArmObservation`, the wrist F/T sensors, the per-step
  record of sensors against the model's ground truth, window means.

:class:`DualArmScene` composes the three. An environment or a capture with its own episode
logic reuses physics and observation::

    physics = DualArmPhysics(DualArmSpec(robot="panda", dt=1e-3))
    observation = DualArmObservation(physics, record=False)  # before the first step (sensor tare)
    physics.clamp(0); physics.clamp(1)                        # grasp both ends
    physics.world.before_step.append(my_controller)           # e.g. robots[i].set_targets(action)
    physics.world.step()
    observation.sensors[0].last.world()                       # left wrist wrench in world, (6,)
    physics.close()
"""
from bullet_dlo.config.robot import DualArmSpec
from bullet_dlo.robots.dual_arm.observation import DualArmObservation, DualArmRecord
from bullet_dlo.robots.dual_arm.physics import ARMS, DualArmPhysics, arm_index
from bullet_dlo.robots.dual_arm.scene import DualArmScene
from bullet_dlo.robots.dual_arm.task import CartesianMove, DualArmTask

DualArmConfig = DualArmSpec  # the name before 0.2 (a scene description is a Spec)

__all__ = ["ARMS", "CartesianMove", "DualArmConfig", "DualArmObservation", "DualArmPhysics", "DualArmRecord",
           "DualArmScene", "DualArmSpec", "DualArmTask", "arm_index"]
