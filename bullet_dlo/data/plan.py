"""Planning an episode: its drawn parameters after the stability-aware policy.

Every episode is checked against the core's stability analysis before it runs. When the
drawn integrator cannot run the drawn step stably (beyond ``SAFETY`` x its critical step),
the spec's policy decides: ``reject`` the sample and draw again (up to ``max_resamples``),
switch to ``implicit`` Euler, or split each Bullet step into integrator ``substeps``. The
decision is returned with the parameters and stored with the episode.
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np

from bullet_dlo.analysis.resolve import resolve_masses, twist_need
from bullet_dlo.config.capture import PARAMETERS, RENAMED, CaptureSpec
from bullet_dlo.config.scene import Scene
from bullet_dlo.sim import resolve_problem
from bullet_dlo.core.boundary import Motion, Move, parse_motion
from bullet_dlo.core.model import CableModel
from bullet_dlo.core.spec import CableSpec
from bullet_dlo.core.stability import critical_dt

SAFETY = 0.9  # run explicit methods at most at 0.9 x their predicted critical step
MAX_SUBSTEPS = 2000


def plan_episode(spec: CaptureSpec, index: int) -> tuple[dict[str, Any], dict[str, Any]]:
    """Parameters of episode ``index`` after the stability policy, and the recorded decision.

    The decision holds the policy, the drawn integrator's critical step [s] (None: unconditionally
    stable), the number of draws, the action taken, the substeps and the resolved number of
    masses (``n_masses: auto`` only).
    """
    attempt = 0
    while True:
        params = spec.draw(index, attempt)
        resolved_n = None
        add_needed_twist(spec, params)
        if params["n_masses"] == "auto":
            params["n_masses"], params["damping"] = auto_masses(spec, params)
            resolved_n = params["n_masses"]
        model = CableModel.straight(cable_spec(params), ends=("clamped", "clamped"))
        crit = critical_dt(model, params["integrator"])
        decision = {"policy": spec.policy, "critical_dt": crit, "attempts": attempt + 1, "action": "none",
                    "substeps": 1, "resolved_n_masses": resolved_n}
        if crit is None or params["dt"] <= SAFETY * crit:
            return params, decision
        if spec.policy == "reject" and attempt + 1 < spec.max_resamples:
            attempt += 1
            continue
        if spec.policy == "substeps" and crit and params["dt"] / (SAFETY * crit) <= MAX_SUBSTEPS:
            decision["substeps"] = int(math.ceil(params["dt"] / (SAFETY * crit)))
            decision["action"] = f"substeps x{decision['substeps']}"
            return params, decision
        decision["action"] = f"switched {params['integrator']} -> implicit_euler"
        if spec.policy == "reject":
            decision["action"] += f" after {attempt + 1} rejected samples"
        params["integrator"] = "implicit_euler"
        return params, decision


def episode_scene(spec: CaptureSpec, params: dict[str, Any]) -> Scene:
    """The episode's cable (10 masses where ``n_masses`` is ``auto``) between two clamps moving as
    :func:`episode_motion`, as ``resolve`` takes a scene."""
    n = 10 if params["n_masses"] == "auto" else params["n_masses"]
    return Scene(cable=cable_spec({**params, "n_masses": n}), motion=episode_motion(params),
                 duration=spec.duration, initial="static", name="episode")


def add_needed_twist(spec: CaptureSpec, params: dict[str, Any]) -> None:
    """An episode whose grippers roll the cable about its axis (or whose section is not round) gets the
    material frame, whatever ``n_masses`` is (:func:`~bullet_dlo.analysis.resolve.twist_need`; without it
    the wrists would read no torsion): ``params["twist"]`` becomes True and ``params["twist_reason"]`` says why."""
    if params.get("twist", False):
        return
    why = twist_need(resolve_problem(episode_scene(spec, params), passages=False))
    if why:
        params["twist"], params["twist_reason"] = True, why


def auto_masses(spec: CaptureSpec, params: dict[str, Any]) -> tuple[int, float]:
    """Number of masses and its k_d [N s/m] for ``n_masses: auto``: a convergence test on the
    episode's own motion (both ends clamped, moving as :func:`episode_motion`), end forces within
    ``spec.resolve_tol``, with the model :func:`add_needed_twist` chose."""
    return resolve_masses(resolve_problem(episode_scene(spec, params)), spec.resolve_tol, "forces")


def episode_motion(params: dict[str, Any]) -> tuple[Motion, ...]:
    """What the grippers do in a planned episode, as core motion items (end first = left gripper, last = right):
    the drawn ``motion`` entries of a spec with a ``motion:`` section, else the right gripper's straight move
    (:func:`gripper_move`, from ``move_start`` [s]; none when its displacement is zero)."""
    if "motion" in params:
        return parse_motion(params["motion"])
    displacement, duration = gripper_move(params)
    return (Move("last", tuple(displacement), params["move_start"], duration),) if duration > 0 else ()


def gripper_move(params: dict[str, Any]) -> tuple[np.ndarray, float]:
    """The right gripper's straight move: displacement [m], shape (3,), and its duration [s] at
    the drawn ``speed`` [m/s] (0 when the displacement is zero: no move)."""
    displacement = np.array([params["displacement_x"], params["displacement_y"], params["displacement_z"]])
    distance = float(np.linalg.norm(displacement))
    return displacement, distance / params["speed"]


def current_names(params: dict[str, Any]) -> dict[str, Any]:
    """An episode's parameters under today's names: episodes stored before the rename
    (:data:`bullet_dlo.config.capture.RENAMED`: ``friction``, ``grip_mu_static``, ``grip_mu_dynamic``)
    read the same. Stored data, not user input: no warning."""
    return {RENAMED.get(k, k): v for k, v in params.items()}


def cable_spec(params: dict[str, Any]) -> CableSpec:
    """The drawn cable; the section's dimensions only where the drawn section uses them (a tube's
    ``inner_diameter``, a rectangle's ``width`` and ``thickness``), so a spec may choose among sections."""
    params = current_names(params)
    section = params.get("section", "round")
    shape = {"tube": ("inner_diameter",), "rectangle": ("width", "thickness")}.get(section, ())
    return CableSpec(length=params["length"], diameter=params["diameter"], mass=params["mass"],
                     youngs_modulus=params["youngs_modulus"], n_masses=params["n_masses"],
                     damping=params["damping"], damping_rate=params.get("damping_rate", 0.0),
                     internal_damping=params.get("internal_damping", 0.0), dynamic_friction=params["dynamic_friction"],
                     static_friction=params.get("static_friction", PARAMETERS["static_friction"][1]["value"]),
                     poisson_ratio=params.get("poisson_ratio", 0.3), section=section,
                     twist=params.get("twist", False), **{k: params[k] for k in shape if k in params})
