"""A contact step whose Newton solve stalls far from convergence is taken again as sub-steps, or the run stops.

The scene: a flat cable falling at 0.5 m/s onto the ground with a normal damper (``contact_damping=1``),
placed so that Newton's start guess for the step, v' = v (no force acts: x' = x + h v), ends exactly at gap
0+. Any Newton direction pushes the cable into the ground, where the damper switches on: the merit jumps by
1/2 c_n (v . n)^2 however short the step, the line search fails on its 30 halvings, and the solve keeps its
start guess. Before the guard (bullet/kernels.py, StallGuard) the cable then moved through that step as if
no force acted (its velocity change was exactly zero), and nothing but a counter said so. Now the step is
taken again as sub-steps, and a coast that is not cured stops the run (status STALLED) with a
RuntimeWarning that says when and how far the solve was from convergence.
"""
from __future__ import annotations

import contextlib
import warnings

import numpy as np
import pytest

from bullet_dlo.bullet import solver as solver_mod
from bullet_dlo.bullet.kernels import COAST_MOVE, COASTED, FIRST_ITER, FIRST_MOVED, FIRST_RATIO, RETRY_SUBSTEPS
from bullet_dlo.bullet.world import BulletWorld
from bullet_dlo.core.engine import NEWTON_WARN_SHARE
from bullet_dlo.core.kernels.monitor import STALLED
from bullet_dlo.core.model import CableState
from bullet_dlo.core.spec import CableSpec
from test_contact_drops import drop

G = 9.81
SPEED = 0.5  # [m/s] downwards
RETRIES = [2 ** k for k in range(1, solver_mod.STALL_RETRIES + 1)]  # the sub-steps a retry may keep


@contextlib.contextmanager
def falling_flat(hz: float, n: int = 10, damping: float = 0.02):
    """A world with the ground and an Lv cable (n nodes, its ``damping`` [N s/m]) lying flat along x, falling at
    SPEED, its height chosen so that x + h v lands exactly at gap 0+ (the smallest float height above the ground's
    contact height r + 0). Yields (world, cable, the start velocities (n, 3)); the cable's first step is planned."""
    spec = CableSpec.lv2017(n_masses=n, damping=damping)
    r, h = spec.diameter / 2, 1.0 / hz
    z = r + h * SPEED
    while (z + h * -SPEED) - r <= 0.0:  # the kernel's X = x + h v' at v' = v, then the gap X_z - 0 - r
        z = np.nextafter(z, 1.0)
    x = np.zeros((n, 3))
    x[:, 0] = np.linspace(-0.15, 0.15, n)
    x[:, 2] = z
    v = np.zeros((n, 3))
    v[:, 2] = -SPEED
    with BulletWorld(dt=h) as world:
        cable = world.add_cable(spec, state=CableState(x, v.copy()), contact_damping=1.0)
        yield world, cable, v


@pytest.mark.parametrize("hz", [60.0, 240.0, 1000.0])
def test_a_landing_that_would_coast_is_taken_again_and_does_not_coast(hz):
    """The first attempt stalls on its start guess (iteration 1, momentum moved by nothing, residual about
    gravity's impulse: below the contact solve's RETRY_RATIO, so no second solve from bounded friction limits; one
    was taken while the ratio was read off the failed line search's direction, 2026-12-07); the step is taken
    again as sub-steps, whose last solve does move the momentum (the
    ground takes the fall: the velocity change is upwards, bounded by what the ground can take without
    creating energy); the run goes on and the cable comes to rest on the ground with its weight supported.

    Measured (demos/newton_stall.py --scenes landing): the retried step still ends about one gravity impulse
    from convergence at every rate, at gap 0 exactly: the damper's force jumps there from 0 to c_n |v . n|, so
    the step's implicit equations have no solution at that point (a property of the contact law, not of the
    solve); it is kept and counted (``far_kept``), not a coast."""
    h = 1.0 / hz
    with falling_flat(hz) as (world, cable, v0):
        info = cable.solver._guard.info
        # the first attempt stalled far from convergence after one iteration, within RETRY_RATIO (steppers.newton:
        # no second solve)
        assert info[FIRST_ITER] == 1 and info[FIRST_RATIO] > solver_mod.STALL_FAR
        assert info[FIRST_MOVED] < COAST_MOVE  # ... on its start guess: a coast
        assert info[RETRY_SUBSTEPS] in RETRIES and cable.solver.stall_retries == 1  # taken again as sub-steps
        assert info[COASTED] == 0.0 and cable.stable  # which did not coast: the run goes on
        dv = (cable._cp.v_new - v0)[:, 2]
        assert np.all(np.abs(dv) > COAST_MOVE * G * h)  # every node's momentum moved (a coast: exactly 0)
        assert np.all(np.abs(v0[:, 2] + dv) <= SPEED + G * h)  # no energy from the ground
        world.step()
        assert np.all(cable.x[:, 2] > cable.radius - 1e-4)  # not into the ground
        world.run(0.5)
        assert cable.stable and cable.solver.coasts == 0
        support = cable.contact_forces()["force"].sum(axis=0)[2]
        assert support == pytest.approx(cable.model.spec.mass * G, rel=0.01)  # lying at rest on the ground
        assert np.abs(cable.v).max() < 1e-3


@pytest.mark.parametrize("hz", [60.0, 240.0, 1000.0])
def test_a_step_taken_again_as_sub_steps_reports_the_ground_force_of_the_whole_step(hz):
    """The retried landing's contact forces are what the cable felt over the Bullet step: without the cable's own
    damping (its drag would act at each sub-step's velocity) the ground's force on the cable is its momentum change
    over the step plus its weight, per step. Before, the rows reported the last sub-step's forces alone, where the
    cable lands: 1.89 N at 60 Hz where the step felt 0.57 N."""
    h = 1.0 / hz
    with falling_flat(hz, damping=0.0) as (world, cable, v0):
        assert cable.solver._guard.info[RETRY_SUBSTEPS] in RETRIES
        m = cable.model.arrays.mass
        felt = np.sum(m * (cable._cp.v_new - v0)[:, 2]) / h + m.sum() * G
        ground = cable.contact_forces()["force"].sum(axis=0)[2]
        assert ground == pytest.approx(felt, rel=1e-6)


def test_an_uncured_coast_stops_the_run_with_when_and_why(monkeypatch):
    """With no retries allowed (STALL_RETRIES = 0) the coast is not cured: the cable stops at once, status
    STALLED, its reason and a RuntimeWarning naming the time and the residual."""
    monkeypatch.setattr(solver_mod, "STALL_RETRIES", 0)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        with falling_flat(240.0) as (world, cable, v0):
            assert not cable.stable and cable.status == STALLED
            assert cable.time_to_instability == 0.0
            assert "stalled" in cable.reason
            x_before = cable.x.copy()
            world.step()  # nothing planned is applied: the cable stays where it stopped
            assert np.array_equal(cable.x, x_before)
    text = [str(w.message) for w in caught if issubclass(w.category, RuntimeWarning)]
    assert any("t = 0 s" in t and "times gravity's impulse" in t and "coast" in t for t in text), text


def test_without_the_guard_the_landing_coasts():
    """The behaviour before the guard (STALL_RETRIES = -1), kept as a switch: the solve keeps its start guess,
    the cable's velocity is unchanged by the step, and the run goes on as stable. This is what the retry
    replaces (the test above fails on that code)."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(solver_mod, "STALL_RETRIES", -1)
        with falling_flat(240.0) as (world, cable, v0):
            assert cable.solver._guard.info[COASTED] == 1.0
            assert np.array_equal(cable._cp.v_new, v0)  # the coast: x' = x + h v, no gravity, no contact
            assert cable.stable and cable.solver.stall_retries == 0


def test_a_converging_contact_run_is_unchanged_by_the_guard():
    """A drop onto a box at 240 Hz (contacts in most steps, every solve converges): bit-identical final state
    with the guard (default: its copies are made before every contact step) and without it (-1: no copies, no
    retry; the code before the guard)."""
    states = []
    for levels in (-1, solver_mod.STALL_RETRIES):
        with pytest.MonkeyPatch.context() as mp:
            mp.setattr(solver_mod, "STALL_RETRIES", levels)
            cable, _, _ = drop("box", "implicit_euler", 240.0, 20, duration=0.5)
        assert cable.stable and cable.newton_failures == 0 and cable.solver.stall_retries == 0
        assert cable.contact_forces()["normal_force"].sum() > 0.0  # it lies on the box: contacts were in the step
        states.append((cable.x.copy(), cable.v.copy()))
    (xa, va), (xb, vb) = states
    assert np.array_equal(xa, xb) and np.array_equal(va, vb)


def _flat(t):
    """The arrays in a tuple and in the tuples it holds (a NamedTuple's fields, its NamedTuples' fields)."""
    for a in t:
        if isinstance(a, tuple):
            yield from _flat(a)
        elif isinstance(a, np.ndarray):
            yield a


def _same_step_from_the_guard(cable) -> list[str]:
    """Take one contact step of ``cable`` from its current state after saving the guard's copies, restore them
    and take the step again (the retry's path, bullet/kernels.py _guarded_contact_step); returns what differs
    between the two steps' results (Newton's count, x, v, every array of the Contacts, its Grip, the Bodies, the
    twist state, the workspace), bit for bit, and asserts that the step did change what the guard restores."""
    from bullet_dlo.bullet.kernels import _copy_rows, _copy_whole
    from bullet_dlo.core.kernels.contact import contact_step
    s = cable.solver
    cp, ws, m = s.coupling, s.workspace, cable.arrays
    c, bd = cable.contacts, cable.contact.bodies
    guard = s.stall_guard(m, c, bd)
    nc = int(c.count[0])
    x0, v0 = cp.x.copy(), cp.v.copy()

    def state():
        return [a.copy() for a in _flat((c, bd, ws))] + [a.copy() for a, _ in guard.whole]

    _copy_rows(guard.rows, nc, True)
    _copy_whole(guard.whole, True)
    results = []
    for attempt in range(2):
        if attempt:
            _copy_rows(guard.rows, nc, False)
            _copy_whole(guard.whole, False)
        x, v = x0.copy(), v0.copy()
        its = contact_step(s.stepper, m, x, v, cp.samples, ws, False, c, bd)
        results.append((its, x, v, state()))
        if not attempt:  # the step wrote some of what the guard restores (else the test would show nothing)
            assert (any(not np.array_equal(live[:nc], copy[:nc]) for live, copy in guard.rows)
                    or any(not np.array_equal(live, copy) for live, copy in guard.whole))
    (i1, x1, v1, s1), (i2, x2, v2, s2) = results
    diff = [name for name, same in (("iterations", i1 == i2), ("x", np.array_equal(x1, x2)),
                                    ("v", np.array_equal(v1, v2))) if not same]
    diff += [f"array {k} {a.shape}" for k, (a, b) in enumerate(zip(s1, s2)) if a.tobytes() != b.tobytes()]
    return diff


def test_a_contact_step_taken_again_from_the_guard_is_the_same_step():
    """The guard saves only what a contact step reads and also writes (bullet/solver.py, CONTACT_ROWS and the
    rest: copying all 56 arrays of the contact set cost 4.6 us a step); a step taken again after restoring them
    is bit for bit the same step, in every array the step touches. Three scenes: a 30 g box resting on a cable on
    the ground (a free body solved in the step), a cable draped over a table edge (WRAP rows) and a cable dragged
    over the ground by one end (sliding rows). Left unrestored one at a time, the rows' points, anchors and
    stick/slide states, the bodies' work, the free body's velocity and the rows' arms each make one of these
    scenes fail (checked once by unhooking each saved array); the caps, normals, impact flag and the grips' state
    are saved because the step overwrites them and reads them in cases these scenes do not reach (a wrap's
    capstan cap, a gripped end; bullet/solver.py, CONTACT_ROWS)."""
    from test_edge_slide import TABLE, layout, soft_cable
    spec = CableSpec.lv2017(n_masses=20, damping=0.02)
    r = spec.diameter / 2
    with BulletWorld(dt=1 / 240) as world:  # the box resting on the cable
        cable = world.add_cable(spec, start=(-0.15, 0, r), direction=(1, 0, 0))
        world.add_box((0.02, 0.02, 0.01), (0.0, 0.0, 2 * r + 0.01), mass=0.03, friction=0.5)
        world.run(0.2)
        assert cable.stable and cable.contact.bodies.active.any()  # the box is in the cable's step
        assert _same_step_from_the_guard(cable) == []
    soft = soft_cable(20)
    x0, _ = layout(soft, 0.3, 0.5, wrapped=True)
    with BulletWorld(dt=1 / 240, ground=False) as world:  # draped over the table's edge
        world.add_box(TABLE, (-TABLE[0], 0.0, -TABLE[2]), friction=soft.static_friction)
        cable = world.add_cable(soft, state=CableState(x0, np.zeros_like(x0)))
        world.run(0.1)
        kinds = cable.contacts.kind[:int(cable.contacts.count[0])]
        assert cable.stable and (kinds == 1).any()  # a WRAP row
        assert _same_step_from_the_guard(cable) == []
    with BulletWorld(dt=1 / 240) as world:  # dragged along the ground: sliding rows
        cable = world.add_cable(spec, start=(-0.15, 0, r), direction=(1, 0, 0))
        world.run(0.05)
        cable.set_external_force(-1, (0.5, 0.0, 0.0))
        world.run(0.1)
        sliding = cable.contacts.state[:int(cable.contacts.count[0])]
        assert cable.stable and (sliding == 1).any()
        assert _same_step_from_the_guard(cable) == []


def test_many_unconverged_steps_warn_once_with_their_share():
    """A cable sliding over a box edge at 1 kHz (tests/bullet/test_edge_slide.py, n = 40, place 0.75, above the
    threshold) ends about 8 % of its steps unconverged (40 % before the bend between two wraps kept only its share,
    2026-12-04), far from convergence but never coasting: the steps are kept (no retry, the run goes on) and one
    RuntimeWarning gives the share (above NEWTON_WARN_SHARE), as the core engine's result does."""
    from test_edge_slide import bracket, hang, soft_cable, threshold
    spec = soft_cable(40)
    _, above = bracket(spec.n_masses, 0.75, threshold(0.3))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        travel, _, cable = hang(spec, above, 0.75, 1000.0, settle=0.2, seconds=0.3)
    s = cable.solver
    assert cable.stable and s.stall_retries == 0 and s.coasts == 0
    assert s.newton_failures > 3 * NEWTON_WARN_SHARE * s.steps_planned and s.far_kept > 0
    assert s.near_misses + s.far_kept == s.newton_failures  # every unconverged step was a contact solve, kept
    text = [str(w.message) for w in caught if issubclass(w.category, RuntimeWarning) and "Newton" in str(w.message)]
    assert len(text) == 1 and "%" in text[0] and "kept" in text[0], text
