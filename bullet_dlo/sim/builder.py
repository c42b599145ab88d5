"""One builder from a typed scene to a simulation: every entry point's runtime comes from here.

``build(scene)`` reads every section of the :class:`~bullet_dlo.config.scene.Scene` or refuses
the scene with one line naming the key and why (a key an engine cannot honour is an error, never
silently dropped):

- ``core``: the cable alone (core engine). Honours cable, layout, ends, motion, gravity,
  integrator, dt, duration, initial, detector, newton; refuses ``bullet:`` (no world to put a
  ground or obstacles in) and ``arms:``.
- ``bullet``: the cable as Bullet spheres. Honours all of ``core`` plus ``bullet:`` (ground,
  ground_height, ground_friction, substeps, self_collision, sync, obstacles); refuses ``arms:``.
- ``arms``: two arms grasp the cable's ends. Honours cable, motion (first end = left arm),
  gravity, integrator, dt, duration, initial (``straight`` or the settled shape), detector,
  newton, ``bullet:`` and ``arms:``; refuses ``layout:`` and ``ends:`` (the grippers place and
  hold the cable).

``n_masses: auto`` / ``dt: auto`` are resolved first (:func:`resolved`).
"""
from __future__ import annotations

import math
from dataclasses import replace

from bullet_dlo.analysis.resolve import ResolveProblem, resolve, twist_need
from bullet_dlo.bullet.world import BulletWorld, add_obstacles
from bullet_dlo.config.robot import DualArmSpec
from bullet_dlo.config.scene import Scene
from bullet_dlo.config.schema import one_of
from bullet_dlo.core.enums import Engine
from bullet_dlo.core.engine import DetectorOptions, SimulationResult, simulate
from bullet_dlo.core.spec import CableSpec
from bullet_dlo.core.validate import ParameterError
from bullet_dlo.robots.dual_arm import DualArmScene
from bullet_dlo.sim.simulation import ArmsSimulation, BulletSimulation, CoreSimulation, Simulation

ENGINES = Engine.names()  # core | bullet | arms (bullet_dlo.core.enums.Engine)
"""What :func:`build` can make (see the module doc)."""


def resolve_problem(scene: Scene, passages: bool = True) -> ResolveProblem:
    """``scene`` as :func:`bullet_dlo.analysis.resolve.resolve` takes it: its cable, duration, the radii of its
    obstacles' cylinders and capsules and its passages (:func:`obstacle_floors`; ``passages`` False leaves the
    passages and the URDFs' cylinders out, for :func:`~bullet_dlo.analysis.resolve.twist_need`, which reads the held
    ends only: they cost a Bullet world, about 20 ms) and a rollout with the core engine (the scene's ends, motion,
    start, Newton and detector settings; no obstacles: the contact floor stands for them)."""
    def run(cable: CableSpec, integrator: str, dt: float, duration: float) -> SimulationResult:
        trial = replace(scene, cable=cable, integrator=integrator, dt=dt, duration=duration)
        model = trial.build_model()
        return simulate(model, integrator, dt, duration, state=trial.initial_state(model), max_records=201,
                        newton=trial.newton, detector=trial.detector)

    model = scene.build_model()  # its held ends and motion: whether the scene rolls a clamp (twist_need)
    if passages:
        widths, radii = obstacle_floors(scene)
    else:
        widths, radii = (), tuple(float(ob["radius"]) for ob in scene.bullet.obstacles
                                  if ob["type"] == "cylinder" and ob.get("contact", True))
    return ResolveProblem(scene.cable, scene.duration, run, radii, widths, (model.first, model.last))


def obstacle_floors(scene: Scene) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """What the scene's obstacles ask of its segments, read in a Bullet world of their own: (widths [m] of the gaps
    between them and the ground that its cable could thread, wider than its diameter and at most its length,
    measured by Bullet's narrow phase; radii [m] of every cylinder and capsule among their links' collision shapes,
    a URDF's child links too). Obstacles with ``contact: false`` are left out."""
    opts = scene.bullet
    if not opts.obstacles:
        return (), ()
    with BulletWorld(ground=opts.ground, ground_height=opts.ground_height) as world:
        add_obstacles(world, opts.obstacles)
        widths = tuple(w for w, _, _ in world.passages(scene.cable.diameter, scene.cable.length))
        return widths, world.round_radii()


def with_needed_twist(scene: Scene) -> Scene:
    """``scene`` with the material frame switched on when it rolls a clamp about the cable's axis
    (:func:`~bullet_dlo.analysis.resolve.twist_need`) and ``twist_reason`` saying why (also for a non-round
    section, whose frame is always on); the scene itself when its cable asks for the frame (``twist: true``)
    or never needs it. Every path does this, whether or not
    anything is ``auto``: a cable without the frame would feel nothing of the roll (zero torsion at the
    wrist), which is silently wrong, not a cheaper model."""
    if scene.cable.twist or scene.twist_reason:  # asked for, or said already
        return scene
    why = twist_need(resolve_problem(scene, passages=False))  # (a non-round section has its frame: only the why is new)
    if not why:
        return scene
    cable = scene.cable if scene.cable.twist_enabled else scene.cable.with_(twist=True)
    return replace(scene, cable=cable, twist_reason=why)


def resolved(scene: Scene) -> Scene:
    """``scene`` with the material frame where it is needed (:func:`with_needed_twist`) and ``n_masses: auto``
    / ``dt: auto`` replaced by the choice of :func:`bullet_dlo.analysis.resolve.resolve`."""
    scene = with_needed_twist(scene)
    if not (scene.auto_n or scene.auto_dt):
        return scene
    r = resolve(resolve_problem(scene), scene.tolerance, scene.tolerance_target)
    new = replace(scene, auto_n=False, auto_dt=False)
    if r.twist and not scene.cable.twist_enabled:  # resolve's own reason (e.g. a non-round section)
        new = replace(new, cable=new.cable.with_(twist=True), twist_reason=r.why)
    if scene.auto_n:
        new = replace(new, cable=new.cable.with_(n_masses=r.n_masses, damping=r.damping))
    if scene.auto_dt:
        new = replace(new, dt=r.dt, integrator=r.integrator)
    return new


def engine_for(scene: Scene, robot: str | None = None) -> str:
    """The engine a scene asks for when the caller does not choose: ``arms`` when it has an ``arms:``
    section naming a robot or ``robot`` is given, else ``bullet``."""
    return "arms" if robot or (scene.arms is not None and scene.arms.robot) else "bullet"


def build(scene: Scene, engine: str | None = None, *, robot: str | None = None, renderer: str | None = None,
          gui: bool = False, command: str = "build", record_every: int | None = None,
          max_records: int = 2001) -> Simulation:
    """The simulation of ``scene`` (see the module doc for what each engine honours and refuses).

    engine: ``core``, ``bullet`` or ``arms`` (None: :func:`engine_for`); robot: the arms' robot (before the
    scene's ``arms.robot``; kuka when neither names one); renderer: Bullet renderer for images (``auto``,
    ``tiny``, ``egl``; None: none); gui: PyBullet's GUI (``bullet`` only); command: named in refusals
    (e.g. ``simulate --engine core``); record_every, max_records: the cable's record (``bullet``: steps
    between rows, default so that about ``max_records`` rows are kept).
    """
    engine = one_of("engine", engine_for(scene, robot) if engine is None else engine, Engine)
    refuse_unused_keys(scene, engine, command)
    scene = resolved(scene)
    if engine == "core":
        return CoreSimulation(scene, scene.build_model())
    if engine == "bullet":
        return build_bullet(scene, scene.detector, gui=gui, renderer=renderer, record_every=record_every,
                            max_records=max_records)
    return build_arms(scene, robot=robot, renderer=renderer)


def refuse_unused_keys(scene: Scene, engine: str, command: str) -> None:
    """A ParameterError naming the first scene section that ``engine`` cannot honour (given in the file)."""
    unused = {"core": ("bullet", "arms"), "bullet": ("arms",), "arms": ("layout", "ends")}[engine]
    why = {"bullet": "the core engine has no world for a ground or obstacles: use --engine bullet",
           "arms": "two arms hold the cable in grasp and render --robot (or give the scene's arms.robot)",
           "layout": "the grippers place the cable between them",
           "ends": "the grippers hold both ends"}
    for key in unused:
        if key in scene.given:
            raise ParameterError(f"{key}: not used by {command} ({why[key]}); remove it from the scene file")


def build_bullet(scene: Scene, detector: DetectorOptions, *, gui: bool = False, renderer: str | None = None,
                 record_every: int | None = None, max_records: int = 2001) -> BulletSimulation:
    """The cable of ``scene`` as Bullet spheres in a world with the scene's ground and obstacles."""
    opts = scene.bullet
    world = BulletWorld(scene.dt, scene.gravity, gui=gui, ground=opts.ground, ground_height=opts.ground_height,
                        ground_friction=opts.ground_friction, renderer=renderer)
    every = (max(1, math.ceil(world.steps_in(scene.duration) / max(1, max_records - 1)))
             if record_every is None else record_every)
    try:
        add_obstacles(world, opts.obstacles)
        model = scene.build_model()
        cable = world.add_cable(model, integrator=scene.integrator, state=scene.initial_state(model),
                                substeps=opts.substeps, self_collision=opts.self_collision, sync=opts.sync,
                                newton=scene.newton, detector=detector, record_every=every)
    except Exception:
        world.close()
        raise
    return BulletSimulation(scene, model, world, cable, lambda det: build_bullet(
        scene, det, gui=gui, renderer=renderer, record_every=every, max_records=max_records))


def build_arms(scene: Scene, *, robot: str | None = None, renderer: str | None = None, grasp: bool = True,
               record: bool = True) -> ArmsSimulation:
    """Two arms holding the cable of ``scene``: both ends grasped (``grasp``), following the scene's motion,
    the wrist sensors' per-step record kept (``record``)."""
    spec = DualArmSpec.from_scene(scene, robot=robot, renderer=renderer)
    arms = DualArmScene(spec, record=record)
    try:
        if grasp:
            arms.grasp()
        arms.follow_motion(scene.motion)
    except Exception:
        arms.close()
        raise
    return ArmsSimulation(scene, arms)

