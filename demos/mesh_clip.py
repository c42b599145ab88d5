"""A Panda pulls a cable through a mesh clip and around a mesh post while a light part rides on it (issue 23).

Two Pandas hold a soft cord (0.6 m, 6 mm, 30 g). It passes through a U-shaped clip (a concave triangle
mesh, ``mesh_clip_clip.obj``) and past a vertical post (a 32-gon prism, a convex mesh,
``mesh_clip_post.obj``); a 20 g saddle-shaped part (three boxes: a bar on the cord and two legs either
side of it) hangs on the cord between them. Both grippers lower the cord into the clip's slot (0.5-2 s),
then the right one pulls it through the clip and round the post while the left one feeds it (2.3-4 s).
Everything the cord meets enters its contact model: the clip through Bullet's narrow phase (a triangle
mesh), the post on the project's exact convex-hull geometry, the part as a dynamic body (three box rows)
whose weight the cord carries.

It prints what it checks, measured independently of the contact model:

* the cord's centre line (its nodes and 20 points on every segment, every step) against the clip's and
  the post's own geometry (the polygons the meshes are built from, signed distance): the deepest
  penetration [mm] (0 when it never enters) and the smallest clearance minus the cord's radius;
* the part stays on the cord: its centre's distance to the centre line, its height, the cord's
  vertical force on it against its weight over the last 0.5 s, and no contact with the floor;
* the wrist forces: the largest and the final magnitude of each tared sensor force [N].

Writes into ``--out`` (default: a new temporary folder): ``scene.mp4``, ``side_by_side.mp4`` (video
left, wrist forces with a time cursor right), ``forces.png``, ``still.png``, ``render.json``, the two
meshes and their URDFs, and ``mesh_clip.json`` (the checks; with ``instability``: when and why the cable's
detector stopped the run). Runs at 240 Hz unless ``--hz`` says otherwise (measured: 60, 80, 120 and 240 Hz pass
every check; 60 Hz: clip deepest 0.000 mm, 100.00 % of both weights carried. Before a mesh's concave corner met
each of its faces, at 60 Hz the cord fell through the clip's slot-end edge and the run stopped at 3.5 s, 3.48 mm
inside the clip: docs/concepts/contact.md, "Concave corners").

Usage: ``python demos/mesh_clip.py [--out DIR] [--quick] [--hz HZ]`` (``--quick``: 1.5 s at 160x120, the cord
lowered into the clip with the part on it; for smoke tests).
"""
from __future__ import annotations

import argparse
import json
import math
import tempfile
import time
from pathlib import Path

import numpy as np
import pybullet as pb

from bullet_dlo.config.scene import Scene
from bullet_dlo.render.pipeline import render_scene

HZ = 240.0
G = 9.81
CORD = {"length": 0.6, "diameter": 0.006, "mass": 0.03, "youngs_modulus": 2.0e7, "n_masses": 24,
        "damping_rate": 1.0, "internal_damping": 0.002, "dynamic_friction": 0.5, "static_friction": 0.6}
HOLD = 0.40  # [m] height of the held ends
# the clip: a U (walls and floor) in the y-z plane, extruded along x over CLIP_X; the cord runs along x in its slot
CLIP_X = (-0.13, -0.09)  # [m]
CLIP_U = [(-0.022, 0.325), (0.022, 0.325), (0.022, 0.375), (0.012, 0.375), (0.012, 0.337),
          (-0.012, 0.337), (-0.012, 0.375), (-0.022, 0.375)]  # [m] (y, z), counter-clockwise
CLIP_STAND = ((0.02, 0.02, 0.16), (-0.11, 0.0, 0.16))  # [m] half extents, centre: a box from the floor up
# the post: a 32-gon of radius POST_R round POST_XY, extruded along z from 0 to POST_H
POST_XY, POST_R, POST_H, POST_SIDES = (0.14, -0.04), 0.015, 0.44, 32
DOWN, SLACK = 0.06, 0.03  # [m] both ends lowered, and moved inwards
PULL = (-0.02, -0.16, 0.0)  # [m] the right end's pull
FEED = 0.02  # [m] the left end moves towards the clip meanwhile: the cord it gives is drawn through the clip
PART_MASS = 0.02  # [kg]
BAR = (0.012, 0.012, 0.003)  # [m] half extents of the part's top bar (across the cord: y)
LEG = (0.012, 0.003, 0.015)  # [m] half extents of each leg, hanging either side of the cord
LEG_Y = 0.011  # [m] the legs' centres off the bar's centre (inner gap 16 mm, the cord 6 mm)
PART_X = 0.0  # [m] where the part is hung on the cord
PHASES = ((0.5, 2.0, "lower into the clip"), (2.3, 4.0, "pull through, round the post"))


def motion(quick: bool) -> list[dict]:
    """Both ends DOWN lower and SLACK inwards (the cord settles into the clip's slot and sags), then the
    right end moves PULL: sideways past the post, which the cord wraps round, while the left one feeds FEED
    towards the clip: the cord is drawn through it."""
    moves = [{"end": "first", "displacement": [SLACK, 0.0, -DOWN], "start": 0.5, "duration": 1.5},
             {"end": "last", "displacement": [-SLACK, 0.0, -DOWN], "start": 0.5, "duration": 1.5}]
    if not quick:
        moves += [{"end": "last", "displacement": list(PULL), "start": 2.3, "duration": 1.7},
                  {"end": "first", "displacement": [FEED, 0.0, 0.0], "start": 2.3, "duration": 1.7}]
    return moves


# ----- the meshes ---------------------------------------------------------------------------------------
def _prism(poly2d, caps, lo: float, hi: float, axis: int) -> tuple[list, list]:
    """Vertices and triangles of a polygon (counter-clockwise in its plane) extruded along ``axis``
    (0: x, the polygon in (y, z); 2: z, the polygon in (x, y)) from ``lo`` to ``hi``: a quad per side and
    the two end caps from ``caps``, convex pieces that tile the polygon (each fanned from its first corner)."""
    def point(p, s):
        return [s, p[0], p[1]] if axis == 0 else [p[0], p[1], s]
    k = len(poly2d)
    verts = [point(p, lo) for p in poly2d] + [point(p, hi) for p in poly2d]
    tris = []
    for i in range(k):  # sides: (e x axis) is outward for a counter-clockwise polygon
        j = (i + 1) % k
        tris += [(i, j, k + j), (i, k + j, k + i)]
    for piece in caps:
        for s, flip in ((lo, True), (hi, False)):
            base = len(verts)
            verts += [point(p, s) for p in piece]
            for m in range(1, len(piece) - 1):
                tris.append((base, base + m + 1, base + m) if flip else (base, base + m, base + m + 1))
    return verts, tris


def _write_obj(path: Path, verts, tris) -> None:
    lines = [f"v {x:.6f} {y:.6f} {z:.6f}" for x, y, z in verts] + [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in tris]
    path.write_text("\n".join(lines) + "\n")


URDF = """<?xml version="1.0"?>
<robot name="{name}">
  <link name="base">
    <inertial><mass value="0"/><inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/></inertial>
    <visual><geometry><mesh filename="{obj}"/></geometry><material name="m"><color rgba="{rgba}"/></material></visual>
    <collision {concave}><geometry><mesh filename="{obj}"/></geometry></collision>
  </link>
</robot>
"""


def post_polygon() -> list[tuple[float, float]]:
    """The post's cross-section: a regular POST_SIDES-gon whose faces lie POST_R from its axis."""
    rv = POST_R / math.cos(math.pi / POST_SIDES)
    return [(POST_XY[0] + rv * math.cos(2 * math.pi * (i + 0.5) / POST_SIDES),
             POST_XY[1] + rv * math.sin(2 * math.pi * (i + 0.5) / POST_SIDES)) for i in range(POST_SIDES)]


def write_meshes(out: Path) -> tuple[Path, Path]:
    """The clip (concave: a static triangle mesh) and the post (a convex hull) as OBJ + URDF in ``out``."""
    floor_top = CLIP_U[4][1]
    (y0, z0), (y1, _), (_, z1), (yi, _) = CLIP_U[0], CLIP_U[1], CLIP_U[2], CLIP_U[3]
    caps = [[(y0, z0), (y1, z0), (y1, floor_top), (y0, floor_top)],  # the floor, then the two walls on it
            [(yi, floor_top), (y1, floor_top), (y1, z1), (yi, z1)],
            [(y0, floor_top), (-yi, floor_top), (-yi, z1), (y0, z1)]]
    _write_obj(out / "mesh_clip_clip.obj", *_prism(CLIP_U, caps, *CLIP_X, axis=0))
    poly = post_polygon()
    _write_obj(out / "mesh_clip_post.obj", *_prism(poly, [poly], 0.0, POST_H, axis=2))
    clip, post = out / "mesh_clip_clip.urdf", out / "mesh_clip_post.urdf"
    clip.write_text(URDF.format(name="clip", obj="mesh_clip_clip.obj", rgba="0.9 0.5 0.1 1", concave='concave="yes"'))
    post.write_text(URDF.format(name="post", obj="mesh_clip_post.obj", rgba="0.3 0.5 0.8 1", concave=""))
    return clip, post


# ----- the independent geometry check ------------------------------------------------------------------------
def polygon_sdf(p: np.ndarray, poly) -> np.ndarray:
    """Signed distance [m] of 2D points p (k, 2) to a closed polygon (negative inside)."""
    v = np.asarray(poly, float)
    w = np.roll(v, -1, axis=0)
    e = w - v  # (m, 2)
    d = p[:, None, :] - v[None]  # (k, m, 2)
    t = np.clip(np.sum(d * e, axis=2) / np.sum(e * e, axis=1), 0.0, 1.0)
    dist = np.linalg.norm(d - t[..., None] * e, axis=2).min(axis=1)
    # inside by the crossing number
    y = p[:, 1][:, None]
    crosses = ((v[:, 1] <= y) != (w[:, 1] <= y)) & (
        p[:, 0][:, None] < v[:, 0] + (y - v[:, 1]) * e[:, 0] / np.where(e[:, 1] == 0, 1e-300, e[:, 1]))
    inside = np.sum(crosses, axis=1) % 2 == 1
    return np.where(inside, -dist, dist)


def prism_sdf(p: np.ndarray, poly, lo: float, hi: float, axis: int) -> np.ndarray:
    """Signed distance [m] of points p (k, 3) to the polygon ``poly`` extruded along ``axis`` from lo to hi."""
    plane = p[:, [1, 2]] if axis == 0 else p[:, [0, 1]]
    d2 = polygon_sdf(plane, poly)
    da = np.abs(p[:, axis] - 0.5 * (lo + hi)) - 0.5 * (hi - lo)
    outside = np.sqrt(np.maximum(d2, 0.0) ** 2 + np.maximum(da, 0.0) ** 2)
    return np.minimum(np.maximum(d2, da), 0.0) + outside


def centre_line(x: np.ndarray, per_segment: int = 20) -> np.ndarray:
    """The nodes and ``per_segment`` points on every segment, (k, 3) [m]."""
    t = np.linspace(0.0, 1.0, per_segment + 1)[:-1, None, None]
    return np.vstack([(x[:-1][None] * (1 - t) + x[1:][None] * t).reshape(-1, 3), x[-1:]])


class Checks:
    """An after-step hook of the running scene: the centre line against the meshes' own geometry, the part."""

    def __init__(self, arm_scene, part: int, radius: float):
        self.world, self.cable, self.part, self.radius = arm_scene.world, arm_scene.cable, part, radius
        self.sdf = {"clip": np.inf, "post": np.inf}
        self.part_rows: list = []  # t, distance to the centre line, height, cable force z, floor contact
        self.in_clip: list = []  # t, arc length [m] from the cord's first end of its point at the clip's middle

    def __call__(self) -> None:
        pts = centre_line(self.cable.x)
        self.sdf["clip"] = min(self.sdf["clip"], float(prism_sdf(pts, CLIP_U, *CLIP_X, axis=0).min()))
        self.sdf["post"] = min(self.sdf["post"], float(prism_sdf(pts, post_polygon(), 0.0, POST_H, axis=2).min()))
        x = self.cable.x
        mid = 0.5 * sum(CLIP_X)
        cross = np.nonzero((x[:-1, 0] - mid) * (x[1:, 0] - mid) <= 0.0)[0]
        if len(cross):
            i = int(cross[0])
            seg = np.linalg.norm(np.diff(x, axis=0), axis=1)
            f = (mid - x[i, 0]) / (x[i + 1, 0] - x[i, 0]) if x[i + 1, 0] != x[i, 0] else 0.0
            self.in_clip.append((self.world.time, float(seg[:i].sum() + f * seg[i])))
        cid = self.world.client
        pos = np.array(pb.getBasePositionAndOrientation(self.part, physicsClientId=cid)[0])
        dist = float(np.linalg.norm(pts - pos, axis=1).min())
        force = self.cable.body_forces().get(self.part, np.zeros(3))
        floor = bool(pb.getContactPoints(self.part, self.world.ground_id, physicsClientId=cid)) \
            if self.world.ground_id is not None else False
        self.part_rows.append((self.world.time, dist, pos[2], float(force[2]), floor))  # force on the part: up


def add_part(world, x: np.ndarray) -> int:
    """The saddle-shaped part hung on the cord at PART_X: a bar resting on it, a leg either side."""
    cid = world.client
    i = int(np.argmin(np.abs(x[:, 0] - PART_X)))
    top = x[i] + (0.0, 0.0, CORD["diameter"] / 2 + BAR[2] + 5e-4)  # the bar's centre, 0.5 mm above the cord
    col = pb.createCollisionShapeArray(
        [pb.GEOM_BOX] * 3, halfExtents=[BAR, LEG, LEG],
        collisionFramePositions=[[0, 0, 0], [0, -LEG_Y, -BAR[2] - LEG[2]], [0, LEG_Y, -BAR[2] - LEG[2]]],
        physicsClientId=cid)
    vis = pb.createVisualShapeArray(
        [pb.GEOM_BOX] * 3, halfExtents=[BAR, LEG, LEG],
        visualFramePositions=[[0, 0, 0], [0, -LEG_Y, -BAR[2] - LEG[2]], [0, LEG_Y, -BAR[2] - LEG[2]]],
        rgbaColors=[[0.2, 0.7, 0.3, 1.0]] * 3, physicsClientId=cid)
    # its centre of mass (uniform density) is 7 mm below the cord's axis, so it hangs on the cord like a
    # pendulum; PyBullet puts it at the frame's origin (the bar's centre) unless told
    v_bar, v_leg = np.prod(BAR), np.prod(LEG)
    com_z = -2 * v_leg * (BAR[2] + LEG[2]) / (v_bar + 2 * v_leg)
    part = pb.createMultiBody(PART_MASS, col, vis, top.tolist(), baseInertialFramePosition=[0.0, 0.0, com_z],
                              physicsClientId=cid)
    pb.changeDynamics(part, -1, lateralFriction=0.6, physicsClientId=cid)
    world.bodies[part] = "part"
    return part


def run(out: Path, quick: bool, hz: float = HZ, size: tuple[int, int] | None = None) -> dict:
    clip, post = write_meshes(out)
    scene = Scene.from_dict({
        "name": "mesh clip", "cable": CORD, "integrator": "implicit_euler", "dt": 1.0 / hz,
        "duration": 1.5 if quick else 5.0, "motion": motion(quick),
        "arms": {"robot": "panda", "hold_height": HOLD, "table_height": 0.0},
        "bullet": {"obstacles": [
            {"type": "box", "half_extents": list(CLIP_STAND[0]), "position": list(CLIP_STAND[1]), "name": "stand",
             "contact": False},  # under the clip: the cord never reaches it
            {"type": "urdf", "path": str(clip), "name": "clip"},
            {"type": "urdf", "path": str(post), "name": "post"}]}})
    state: dict = {}

    def on_arm_scene(arm_scene) -> None:
        world = arm_scene.world
        part = add_part(world, arm_scene.cable.x)
        checks = Checks(arm_scene, part, CORD["diameter"] / 2)
        meshes = {name: body for body, name in world.bodies.items() if name in ("clip", "post")}

        def last_forces() -> None:  # the cord's force on each mesh after the step [N]
            forces = arm_scene.cable.body_forces()
            state["mesh_forces"] = {name: forces.get(b, np.zeros(3)).tolist() for name, b in meshes.items()}
            state.setdefault("mesh_z", []).append((world.time, sum(f[2] for f in state["mesh_forces"].values())))

        world.after_step += [checks, last_forces]
        state.update(arm_scene=arm_scene, checks=checks)

    size = size or ((160, 120) if quick else (640, 480))
    tic = time.process_time()  # the whole process: the renderer's threads too
    summary = render_scene(scene, out, width=size[0], height=size[1], phases=PHASES, progress=False,
                           still_time=None if quick else 4.6, on_arm_scene=on_arm_scene)
    cpu = time.process_time() - tic
    checks = state["checks"]
    rows = np.array(checks.part_rows, dtype=float)
    last = rows[:, 0] > rows[-1, 0] - 0.5
    weight = PART_MASS * G
    record = state["arm_scene"].record.arrays()
    wrench = record["wrench_world"][:, :, :3]
    # statics of cord and part together: what the grippers (tared wrist sensors: the cable's force on each) and
    # the meshes (the contact model's force on them) carry, against both weights, over the last 0.5 s
    mesh_t, mesh_z = np.array(state["mesh_z"]).T
    grip_z = wrench[:, 0, 2] + wrench[:, 1, 2]
    carried = -(grip_z[record["t"] > record["t"][-1] - 0.5].mean() + mesh_z[mesh_t > mesh_t[-1] - 0.5].mean())
    magnitude = np.linalg.norm(wrench, axis=2)  # (k, 2)
    r = CORD["diameter"] / 2
    solver = state["arm_scene"].cable.solver
    clip_t, clip_s = np.array(checks.in_clip).T  # arc length at the clip's middle: how much was drawn through
    result = {
        "stable": summary["stable"], "cpu_s": cpu,
        # when and why the cable's detector stopped the run (None: it did not)
        "instability": (None if summary["stable"] else
                        {"reason": state["arm_scene"].cable.reason,
                         "time_s": state["arm_scene"].cable.time_to_instability}), "frames": summary["frames"],
        "penetration_mm": {k: 1e3 * max(0.0, -v) for k, v in checks.sdf.items()},
        "clearance_minus_radius_mm": {k: 1e3 * (v - r) for k, v in checks.sdf.items()},
        "part": {"max_distance_to_centre_line_mm": 1e3 * float(rows[:, 1].max()),
                 "final_height_m": float(rows[-1, 2]),
                 "support_over_weight_last_0.5s": float(rows[last, 3].mean() / weight),
                 "touched_floor": bool(rows[:, 4].any())},
        "wrist_force_N": {"max": magnitude.max(axis=0).tolist(), "final": magnitude[-1].tolist()},
        "supports_over_weights_last_0.5s": float(carried / ((CORD["mass"] + PART_MASS) * G)),
        "force_on_mesh_N": state["mesh_forces"],  # at the end: the cord on the clip and on the post
        # cord drawn through the clip (to the right) since the pull began (None: the run ended before it)
        "drawn_through_clip_mm": (1e3 * (clip_s[np.searchsorted(clip_t, PHASES[1][0])] - clip_s[-1])
                                  if clip_t[-1] > PHASES[1][0] else None),
        "sensor_check_failures": len(summary.get("sensor_check", {}).get("failures", [])),
        # the cable's Newton solves: how many steps ended unconverged (a light part on the cord makes many:
        # docs/concepts/contact.md, Limits), and the worst residual kept, in units of gravity's impulse in a step
        "newton": {"failed_steps": solver.newton_failures, "planned_steps": solver.steps_planned,
                   "worst_kept_ratio": solver.worst_kept_ratio},
        "video": summary.get("side_by_side"),
        # the part every 0.1 s: t [s], distance to the centre line [m], height [m], cord's force up / its weight
        "part_track": [[round(v, 4) for v in (row[0], row[1], row[2], row[3] / weight)] for row in rows[::max(1, round(0.1 * hz))]],
    }
    # on the cord: its centre within the bar's half height + the cord's radius + the legs' reach of the centre line
    result["part"]["on_cable"] = (result["part"]["max_distance_to_centre_line_mm"] < 1e3 * (r + 2 * BAR[2] + LEG[2])
                                  and not result["part"]["touched_floor"])
    (out / "mesh_clip.json").write_text(json.dumps(result, indent=2))
    return result


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=None, help="output folder (default: a new temporary folder)")
    ap.add_argument("--quick", action="store_true", help="1.5 s at 160x120: the cord lowered into the clip")
    ap.add_argument("--hz", type=float, default=HZ, help=f"physics rate [Hz] (default {HZ:g})")
    ap.add_argument("--size", default=None, metavar="WxH",
                    help="video size in pixels, each 16-1920 (default 640x480; --quick: 160x120)")
    args = ap.parse_args()
    size = None
    if args.size is not None:
        try:
            size = tuple(int(v) for v in args.size.lower().split("x"))
        except ValueError:
            size = ()
        if len(size) != 2 or not all(16 <= v <= 1920 for v in size):
            ap.error(f"--size must be WxH with each of W, H in 16-1920 pixels, got {args.size!r}")
    if not (math.isfinite(args.hz) and args.hz >= 10.0):
        ap.error(f"--hz must be a physics rate of at least 10 Hz, got {args.hz:g}")  # one line, exit 2
    out = Path(args.out) if args.out else Path(tempfile.mkdtemp(prefix="mesh_clip_"))
    out.mkdir(parents=True, exist_ok=True)
    res = run(out, args.quick, args.hz, size)
    pen, clr = res["penetration_mm"], res["clearance_minus_radius_mm"]
    part = res["part"]
    print(f"cable stable: {res['stable']}; {res['frames']} frames; {res['cpu_s']:.1f} s CPU")
    nw = res["newton"]
    print(f"Newton solves unconverged in {nw['failed_steps']} of {nw['planned_steps']} steps (worst kept at "
          f"{nw['worst_kept_ratio']:.3g} times gravity's impulse in a step)")
    if res["instability"]:
        print(f"the run stopped at t = {res['instability']['time_s']:.3f} s: {res['instability']['reason']}")
    print(f"centre line inside the clip mesh: deepest {pen['clip']:.3f} mm; inside the post mesh: deepest "
          f"{pen['post']:.3f} mm (smallest clearance minus the cord's radius: clip {clr['clip']:+.3f} mm, "
          f"post {clr['post']:+.3f} mm)")
    print(f"part on the cable: {part['on_cable']} (its centre at most {part['max_distance_to_centre_line_mm']:.1f} mm "
          f"from the centre line, final height {part['final_height_m']:.3f} m, the cord carries "
          f"{100 * part['support_over_weight_last_0.5s']:.1f} % of its weight over the last 0.5 s, floor touched: "
          f"{part['touched_floor']})")
    fmax, ffin = res["wrist_force_N"]["max"], res["wrist_force_N"]["final"]
    fc, fp = (np.linalg.norm(res["force_on_mesh_N"][k]) for k in ("clip", "post"))
    drawn = res["drawn_through_clip_mm"]
    print(("" if drawn is None else f"cord drawn through the clip since the pull began: {drawn:.1f} mm; ")
          + f"the cord's force at the end on the clip {fc:.3f} N, on the post {fp:.3f} N")
    print(f"grippers and meshes carry {100 * res['supports_over_weights_last_0.5s']:.2f} % of the cord's and the "
          f"part's weight over the last 0.5 s")
    print(f"wrist force |F|: left max {fmax[0]:.3f} N, final {ffin[0]:.3f} N; right max {fmax[1]:.3f} N, final "
          f"{ffin[1]:.3f} N; sensor check failures: {res['sensor_check_failures']}")
    print(f"\noutputs written to {out.resolve()}")


if __name__ == "__main__":
    main()
