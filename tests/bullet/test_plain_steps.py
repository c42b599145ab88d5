"""Plain steps (bullet.plain_steps): a world's step in one compiled call gives the Python phases' results to the bit.

Each scene runs twice, with plain steps and with every step in Python's phases (``PLAIN_STEPS = False``), and every
state, record row, counter and stop report must be equal. The speed is measured by ``python demos/step_breakdown.py``
(ratios, not timed tests); here also: the plain loop was taken, and the steps it hands back to Python (a body that
moved, a step to book) are booked as Python books them.
"""
from __future__ import annotations

import numpy as np
import pybullet as pb
import pytest

from bullet_dlo.bullet import native, plain_call, plain_steps
from bullet_dlo.bullet.world import BulletWorld
from bullet_dlo.core.boundary import Move
from bullet_dlo.core.model import CableModel
from bullet_dlo.core.spec import CableSpec

pytestmark = pytest.mark.skipif(native.plugin_library() is None or not native.enabled(),
                                reason="no native Bullet calls here (no C compiler, or switched off): no plain steps")

COUNTERS = ("steps_planned", "newton_iterations", "newton_failures", "stall_retries", "near_misses", "far_kept",
            "coasts", "last_ratio", "status", "time_to_instability", "stop_report")


def _outcome(world: BulletWorld, cable) -> dict:
    out = {"x": cable.x.copy(), "v": cable.v.copy(), "t": cable.t, "steps": cable.steps, "time": world.time,
           "world_steps": world.steps, "contacts": cable.contacts_last_step}
    out.update({f"twist_{k}": a.copy() for k, a in cable.state().twist._asdict().items()})
    out.update({f"twist_planned_{k}": a.copy() for k, a in cable.twist._asdict().items()})
    out.update({f"record_{k}": a for k, a in cable.record.arrays().items()})
    out.update({k: getattr(cable.solver, k) for k in COUNTERS})
    return out


def _run(monkeypatch, plain: bool, build, chunks, between=None) -> tuple[dict, int]:
    """Build a world (``build(world)`` returns the cable), step it ``chunks`` (a list of step counts, one
    ``world.step`` call each; ``between(world, k)`` after call k); returns the outcome and the steps taken plain."""
    monkeypatch.setattr(plain_steps, "PLAIN_STEPS", plain)
    monkeypatch.setattr(plain_steps, "PLAIN_FROM", 0)  # (plain from the first step: these runs are short)
    taken = []
    take = plain_steps.take

    def counted(world, n, horizon=0):
        k = take(world, n, horizon)
        taken.append(k)
        return k
    monkeypatch.setattr(plain_steps, "take", counted)
    world, cable = build()
    with world:
        for k, n in enumerate(chunks):
            world.step(n)
            if between is not None:
                between(world, k)
        return _outcome(world, cable), sum(taken)


def _same(a: dict, b: dict) -> None:
    for k in a:
        if isinstance(a[k], np.ndarray):
            assert np.array_equal(a[k], b[k]), k
        else:
            assert a[k] == b[k], (k, a[k], b[k])


def _clamped_moving(record_every: int = 1):
    """The study's cable (n 10, clamped both ends, the last moved 5 mm) above the ground at 1 kHz."""
    world = BulletWorld(dt=1e-3)
    spec = CableSpec.lv2017(n_masses=10, youngs_modulus=126e6, damping=0.01)
    model = CableModel.straight(spec, ends=("clamped", "clamped"), motion=[Move("last", (0, 0, 0.005), 0.1, 0.1)])
    return world, world.add_cable(model, record_every=record_every)


def _twisting(ends: str = "clamped"):
    """A cable with a material frame (n 12, both ends held in ``ends``: clamps, or forks) on a table at 1 kHz, its last
    end turned a quarter turn about the cable and moved 2 cm in 0.2 s: the twist springs load the holders."""
    world = BulletWorld(dt=1e-3, ground=False)
    TABLES[world.client] = world.add_box((0.3, 0.1, 0.05), (0.0, 0.0, -0.05), friction=0.5, name="table")
    spec = CableSpec.lv2017(n_masses=12, twist=True, damping=0.02)
    model = CableModel.straight(spec, start=(-0.15, 0.0, spec.diameter / 2 + 0.002), ends=(ends, ends),
                                motion=[Move("last", (-0.02, 0.0, 0.0), 0.0, 0.2, rotation=(np.pi / 2, 0.0, 0.0))])
    return world, world.add_cable(model)


def _torn(start: float = 0.01):
    """The study's cable with its last end yanked 2 m in 20 ms from ``start`` [s]: the strain check stops it."""
    world = BulletWorld(dt=1e-3)
    spec = CableSpec.lv2017(n_masses=10, damping=0.01)
    model = CableModel.straight(spec, ends=("clamped", "clamped"), motion=[Move("last", (2.0, 0, 0), start, 0.02)])
    return world, world.add_cable(model)


TABLES: dict[int, int] = {}  # {world's client: its table}


def _on_a_table():
    """A free cable dropped 5 mm onto a static box at 240 Hz: contact rows, friction and landing every step."""
    world = BulletWorld(dt=1 / 240, ground=False)
    TABLES[world.client] = world.add_box((0.3, 0.1, 0.05), (0.0, 0.0, -0.05), friction=0.5, name="table")
    spec = CableSpec.lv2017(n_masses=15, damping=0.02)
    return world, world.add_cable(spec, start=(-0.15, 0.0, spec.diameter / 2 + 0.005), direction=(1, 0, 0))


@pytest.mark.parametrize("record_every", [1, 7])
def test_a_clamped_cable_moved_by_its_end_steps_plain_to_the_same_bits(monkeypatch, record_every):
    """One step a call, then long calls: 1500 steps, the record's block filled and moved several times."""
    chunks = [1] * 50 + [450, 1000]
    plain, n_plain = _run(monkeypatch, True, lambda: _clamped_moving(record_every), chunks)
    python, n_python = _run(monkeypatch, False, lambda: _clamped_moving(record_every), chunks)
    assert n_python == 0 and n_plain > 1400, n_plain
    assert plain["record_t"].shape[0] > 2 * 256 // record_every  # (blocks of at most 256 rows)
    _same(plain, python)


def test_a_cable_landing_on_a_table_steps_plain_to_the_same_bits(monkeypatch):
    plain, n_plain = _run(monkeypatch, True, _on_a_table, [240])
    python, _ = _run(monkeypatch, False, _on_a_table, [240])
    assert n_plain > 200 and plain["contacts"] > 0
    _same(plain, python)


def test_before_detection_is_loaded_a_stand_in_hands_each_detecting_step_to_python(monkeypatch):
    """Until the process has loaded detection the loop holds a stand-in (``no_detect``): the first step that needs
    detection is handed to Python after Bullet's step (which detects, as the Python phases do, loading it), the
    arguments are packed anew with the real detection, the other steps stay plain, and the results are the same
    bits."""
    python, _ = _run(monkeypatch, False, _on_a_table, [10, 30, 200])
    asked = []

    def loaded(detect_args):  # (not loaded when first asked, then as it is: loaded by the Python step)
        asked.append(detect_args)
        return len(asked) > 1
    monkeypatch.setattr(plain_steps, "_detection_loaded", loaded)
    handed = []
    run = plain_steps.run

    def counted(*a):
        out = run(*a)
        handed.append(out[1] == plain_call.DETECT)
        return out
    monkeypatch.setattr(plain_steps, "bind", lambda kernel, *args: counted)
    stand_in, n_plain = _run(monkeypatch, True, _on_a_table, [10, 30, 200])
    assert n_plain > 0 and sum(handed) == 1 and len(asked) == 2, (n_plain, sum(handed), len(asked))
    _same(stand_in, python)


@pytest.mark.parametrize("ends", ["clamped", "fork"])
def test_a_twisting_cable_steps_plain_to_the_same_bits(monkeypatch, ends):
    """A cable with a material frame, its clamp (or fork) rolled and moved on a table: plain after its first step
    (which keeps Python's phases), every state, twist state, record row (the holders' torques with the twist's) and
    counter equal."""
    def outcome(plain):
        out, n_plain = _run(monkeypatch, plain, lambda: _twisting(ends), [1, 150, 150])
        return out, n_plain
    plain, n_plain = outcome(True)
    python, _ = outcome(False)
    assert n_plain == 300, n_plain
    _same(plain, python)


def test_a_static_body_moved_between_steps_hands_the_step_to_python(monkeypatch):
    """The table is moved 0.2 mm up by the user every 10 steps: the plain loop finds it moved after Bullet's step and
    leaves the cable's step to Python, which updates the shape; the same bits as Python's phases all along."""
    def lift(world, k):
        table = TABLES[world.client]
        pos, orn = pb.getBasePositionAndOrientation(table, physicsClientId=world.client)
        pb.resetBasePositionAndOrientation(table, (pos[0], pos[1], pos[2] + 2e-4), orn, physicsClientId=world.client)

    plain, n_plain = _run(monkeypatch, True, _on_a_table, [10] * 24, lift)
    python, _ = _run(monkeypatch, False, _on_a_table, [10] * 24, lift)
    assert 0 < n_plain < 240
    _same(plain, python)


def test_a_cable_torn_by_its_end_stops_at_the_same_step_with_the_same_report(monkeypatch):
    """The last end yanked 2 m in 20 ms: the strain check stops the cable inside the plain loop, booked by Python."""
    plain, n_plain = _run(monkeypatch, True, _torn, [100])
    python, _ = _run(monkeypatch, False, _torn, [100])
    assert plain["status"] != 0 and n_plain > 0, (plain["status"], n_plain)
    _same(plain, python)


def test_a_hook_keeps_every_step_in_python(monkeypatch):
    """An after_step hook (user code between steps) makes no step plain, and changes no result."""
    def hooked():
        world, cable = _clamped_moving()
        world.after_step.append(lambda: None)
        return world, cable

    hooked_out, n_hooked = _run(monkeypatch, True, hooked, [300])
    plain, _ = _run(monkeypatch, True, _clamped_moving, [300])
    assert n_hooked == 0
    _same(hooked_out, plain)


def test_without_numbas_address_helper_every_step_keeps_pythons_phases(monkeypatch):
    """The loop finds the kernels' addresses through a private Numba helper: where a Numba lacks it, no step is
    plain and the results are the same."""
    plain, n_plain = _run(monkeypatch, True, _clamped_moving, [300])
    monkeypatch.setattr(plain_steps, "_get_wrapper_address", None)
    without, n_without = _run(monkeypatch, True, _clamped_moving, [300])
    assert n_plain > 0 and n_without == 0
    _same(without, plain)


def test_run_while_stable_stops_at_the_unstable_step_and_reports_progress(monkeypatch):
    """``run_while_stable`` steps in plain batches (told to ``progress`` every PROGRESS_EVERY steps) and stops after
    the step the cable went unstable in, as stepping one at a time and checking did."""
    monkeypatch.setattr(plain_steps, "PLAIN_FROM", 0)
    world, cable = _torn(0.25)
    told = []
    with world:
        world.run_while_stable(500, cable, told.append)
        plain = (world.steps, cable.steps, cable.solver.time_to_instability, sum(told))
        batched = cable._plain_args is not None
    world, cable = _torn(0.25)
    with world:
        for _ in range(500):
            world.step()
            if not cable.stable:
                break
        one_by_one = (world.steps, cable.steps, cable.solver.time_to_instability, world.steps)
    assert not cable.stable and plain == one_by_one, (plain, one_by_one)
    assert batched and len(told) > 1  # (plain batches, progress told more than once)


def test_a_short_run_keeps_pythons_phases_and_a_long_one_is_plain_from_its_start(monkeypatch):
    """Plain steps start where the run will reach PLAIN_FROM world steps (the loop's code costs a load per process
    that only a long run pays back): a run asked for fewer steps takes none; one asked for more takes them from its
    first step (its length known from ``step(n)``)."""
    monkeypatch.setattr(plain_steps, "PLAIN_FROM", 1000)
    world, cable = _clamped_moving()
    with world:
        world.step(500)
        short = cable._plain_args
        world.step(600)  # reaches 1100 >= PLAIN_FROM: plain from its first step
        assert short is None and cable._plain_args is not None
        assert world.steps == 1100 and cable.solver.steps_planned == 1101
