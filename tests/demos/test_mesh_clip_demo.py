"""demos/mesh_clip.py runs in its --quick form (the pattern of test_demos.py): the cord lowered into the mesh
clip's slot with the 20 g part hanging on it, filmed beside the wrist forces.

Checked against geometry and statics, not against the contact model's own numbers: the centre line (nodes
and 20 points per segment, every step) never enters the clip's polygon (signed distance from the demo's
own description of the mesh), and the cord rests on the clip (its surface within 1 mm of the mesh: the
cord is not held off it either); the part stays on the cord (its centre of mass within reach of the
centre line, never on the floor) and the cord carries its weight (vertical force within 10 % of m g over
the last 0.5 s, while the ends are still being lowered); the two wrist sensors and the clip together carry
the cord's and the part's weight (within 5 %); every wrist sample agrees with the cable's load (the sensor
check).

The whole demo at 120 Hz is not a test: with the 20 g part on the cord 30 % of its contact solves end unconverged,
so whether the part stays on is chaotic in round-off (kept on one machine, thrown off at 3.74 s on another with the
same code; docs/concepts/integrators.md, "A stalled contact step").
"""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]

pytestmark = pytest.mark.bullet


def test_mesh_clip_demo_quick(tmp_path):
    res = subprocess.run([sys.executable, str(ROOT / "demos" / "mesh_clip.py"), "--quick", "--out", str(tmp_path)],
                         capture_output=True, text=True, timeout=900)
    assert res.returncode == 0, res.stderr[-3000:]
    assert f"outputs written to {tmp_path.resolve()}" in res.stdout
    for name in ("side_by_side.mp4", "scene.mp4", "forces.png"):
        assert (tmp_path / name).stat().st_size > 1000, name
    data = json.loads((tmp_path / "mesh_clip.json").read_text())
    assert data["stable"]
    assert data["penetration_mm"] == {"clip": 0.0, "post": 0.0}  # the centre line never inside a mesh
    assert -0.5 < data["clearance_minus_radius_mm"]["clip"] < 1.0  # the cord lies on the clip's floor
    assert "deepest 0.000 mm" in res.stdout
    part = data["part"]
    assert part["on_cable"] and not part["touched_floor"]
    assert part["support_over_weight_last_0.5s"] == pytest.approx(1.0, abs=0.1)
    # cord and part together: the grippers' wrist sensors and the clip carry both weights (the ends still
    # decelerate as they are lowered: measured 102.4 %; 99.8 % at rest at the end of the full run)
    assert data["supports_over_weights_last_0.5s"] == pytest.approx(1.0, abs=0.05)
    assert data["sensor_check_failures"] == 0
    assert all(f > 0.0 for f in data["wrist_force_N"]["final"])
    # the Newton solves are reported (not a bound on them: docs/concepts/contact.md, Limits), for every planned step
    nw = data["newton"]
    assert nw["planned_steps"] >= round(1.5 * 240) - 1 and 0 <= nw["failed_steps"] <= nw["planned_steps"]
    assert f"Newton solves unconverged in {nw['failed_steps']} of {nw['planned_steps']} steps" in res.stdout


def test_the_demos_geometry_is_the_meshes_it_loads(tmp_path):
    """The signed distance the demo checks the centre line with is the meshes Bullet holds: from 300+ points
    2-20 mm outside the clip (a concave triangle mesh, no margin) Bullet's distance equals it within 1e-6 m;
    from the post (a convex hull, grown by Bullet's 1 mm margin) it is 1 mm less within 1e-5 m; and points
    inside are negative (the post's axis: minus its radius; the clip's slot is outside, by its half width)."""
    import numpy as np
    import pybullet as pb
    from demo_module import load

    mc = load("mesh_clip")
    clip, post = mc.write_meshes(tmp_path)
    cid = pb.connect(pb.DIRECT)
    try:
        bodies = {"clip": pb.loadURDF(str(clip), useFixedBase=True, physicsClientId=cid),
                  "post": pb.loadURDF(str(post), useFixedBase=True, physicsClientId=cid)}
        probe_r = 1e-4
        probe = pb.createCollisionShape(pb.GEOM_SPHERE, radius=probe_r, physicsClientId=cid)
        rng = np.random.default_rng(0)
        cases = {"clip": (mc.CLIP_U, *mc.CLIP_X, 0, (-0.11, 0.0, 0.35), 0.0),
                 "post": (mc.post_polygon(), 0.0, mc.POST_H, 2, (*mc.POST_XY, 0.3), 1e-3)}
        for name, (poly, lo, hi, axis, centre, margin) in cases.items():
            pts = np.array(centre) + rng.uniform(-0.04, 0.04, (400, 3))
            sdf = mc.prism_sdf(pts, poly, lo, hi, axis)
            keep = (sdf > 0.002) & (sdf < 0.02)
            assert keep.sum() > 100
            bullet = np.array([min(h[8] for h in pb.getClosestPoints(-1, bodies[name], 0.05, -1, -1, probe, -1,
                                                                     p.tolist(), physicsClientId=cid)) + probe_r
                               for p in pts[keep]])
            assert np.abs(bullet - (sdf[keep] - margin)).max() < (1e-6 if margin == 0.0 else 1e-5), name
        axis_point = np.array([[*mc.POST_XY, 0.2]])
        assert mc.prism_sdf(axis_point, mc.post_polygon(), 0.0, mc.POST_H, 2)[0] == pytest.approx(-mc.POST_R, abs=1e-9)
        slot = np.array([[-0.11, 0.0, 0.35]])
        assert mc.prism_sdf(slot, mc.CLIP_U, *mc.CLIP_X, 0)[0] == pytest.approx(0.012, abs=1e-9)
    finally:
        pb.disconnect(cid)
