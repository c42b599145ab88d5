"""``bullet-dlo resolve``: the fewest masses, cheapest integrator and largest step meeting a tolerance."""
from __future__ import annotations

import argparse

from bullet_dlo.cli.outputs import add_plot_options, plot_path, print_outputs
from bullet_dlo.cli.quiet import elapsed
from bullet_dlo.cli.simulate import write_json


def cmd_resolve(args: argparse.Namespace) -> int:
    from bullet_dlo.analysis.resolve import resolve
    from bullet_dlo.config.scene import Scene
    from bullet_dlo.sim import resolve_problem
    from bullet_dlo.core.validate import check_in_range

    check_in_range("--tol", args.tol, 1e-6, 1.0, open_hi=True)
    scene = Scene.from_yaml(args.scene)
    if args.rollout is not None:  # at most the scene's duration: a trial never outlasts the run it stands for
        check_in_range("--rollout [s]", args.rollout, scene.dt, scene.duration)
    with elapsed("resolve: convergence trials", args.quiet):
        r = resolve(resolve_problem(scene), args.tol, args.target, args.rollout)
    print(f"{scene.name}: n_masses = {r.n_masses}, integrator = {r.integrator}, dt = {r.dt:.4g} s; predicted error "
          f"{r.predicted_error:.4f} (spatial {r.spatial_error:.4f} + temporal {r.temporal_error:.4f}) <= "
          f"{r.tolerance} on {r.target}; {r.wall_time_per_sim_s:.4f} s wall per simulated second")
    if r.why:
        print(f"why n = {r.n_masses}: {r.why}")
    if args.json:
        write_json(args.json, r.to_dict())
    png = plot_path(args, args.json)
    if png is not None:
        from bullet_dlo.render.plots import plot_resolve

        plot_resolve(r.trials, r.tolerance, png, title=f"{scene.name}: resolve on {r.target}")
    print_outputs(args.json, png)
    return 0


def add_parsers(sub, common: argparse.ArgumentParser) -> None:
    """``resolve`` on ``sub`` (argparse subparsers); ``common``: shared options."""
    s = sub.add_parser("resolve", parents=[common], help="fewest masses, integrator and largest step meeting a "
                       "tolerance", description="Convergence tests on a short rollout of SCENE.yaml pick the "
                       "fewest masses, then the cheapest integrator and largest step, that keep the error on what "
                       "the scene needs within --tol. Scenes may also say n_masses: auto / dt: auto.")
    s.add_argument("scene", help="scene YAML file")
    s.add_argument("--tol", type=float, default=0.01, help="relative tolerance (default 0.01)")
    s.add_argument("--target", default="both", choices=["forces", "shape", "both"],
                   help="what must be accurate: end forces and moments (0.2 s means), final shape, or both (default)")
    s.add_argument("--rollout", type=float, default=None, help="seconds simulated per trial (default: the scene's "
                   "duration, at most 2)")
    s.add_argument("--json", metavar="OUT.json", help="write n_masses, dt, integrator, predicted_error, "
                   "wall_time_per_sim_s and the trials")
    add_plot_options(s, "the trials' spatial error against n and temporal error against dt")
    s.set_defaults(func=cmd_resolve)
