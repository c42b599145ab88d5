"""``bullet-dlo view RUN --out PAGE.html``: a recorded run as a self-contained browser page, or live.

RUN is what :func:`bullet_dlo.data.runs.load_run` reads (a capture or rollout directory, an
episode ``.h5``, a ``grasp``/``render --series`` or ``simulate --npz`` file, a ``render`` output
directory); the page is :func:`bullet_dlo.render.viewer.write_viewer`'s. ``--serve`` shows it
at http://127.0.0.1:PORT instead, until Ctrl-C. Bad input (a missing or unreadable RUN, an
``--out`` not ending in .html, viser missing) ends with one ``error:`` line and exit code 2.
"""
from __future__ import annotations

import argparse
from pathlib import Path


def cmd_view(args: argparse.Namespace) -> int:
    from bullet_dlo.core.validate import ParameterError, check_int
    from bullet_dlo.render.viewer import require_viser

    if args.page is None and not args.serve:
        raise ParameterError("view: give --out PAGE.html, --serve, or both")
    if args.page is not None:
        from bullet_dlo.config.schema import output_file

        if Path(args.page).suffix.lower() not in (".html", ".htm"):
            raise ParameterError(f"--out must end in .html (one self-contained page), got {args.page!r}")
        output_file("--out", args.page)
    check_int("--max-frames", args.max_frames, 1, 100_000)
    if args.port is not None:
        check_int("--port", args.port, 1024, 65535)
    if args.episode is not None:
        check_int("--episode", args.episode, 0)
    require_viser()
    scene = None
    if args.scene:
        from bullet_dlo.config.scene import Scene

        scene = Scene.from_yaml(args.scene)
    from bullet_dlo.data.runs import load_run
    from bullet_dlo.render.viewer import serve, write_viewer

    run = load_run(args.run, episode=args.episode, scene=scene)
    if args.page is not None:
        info = write_viewer(run, args.page, max_frames=args.max_frames)
        print(f"{run.source}: {info.frames} frames over {info.duration:.3f} s; {', '.join(info.entities)} -> "
              f"{info.path} ({info.bytes / 1e6:.1f} MB; open it in a browser)")
    if args.serve:
        try:
            serve(run, port=args.port, max_frames=args.max_frames,
                  ready=lambda url: print(f"serving {run.source} at {url} (Ctrl-C stops)", flush=True))
        except KeyboardInterrupt:
            print("stopped", flush=True)
    return 0


def add_parsers(sub, common: argparse.ArgumentParser) -> None:
    """``view`` on ``sub`` (argparse subparsers)."""
    s = sub.add_parser("view", parents=[common], help="a run or episode in the browser: cable, arms, wrenches, "
                       "contacts, a timeline (pip install 'bullet-dlo[view]')",
                       description="Write RUN as one self-contained HTML page (viser's viewer with the recording "
                                   "inlined; it opens from disk, no server or network) showing the cable (line strip "
                                   "and masses), both arms from their URDFs at the recorded joint angles, ground, "
                                   "table and obstacles, the wrist forces as arrows and as a time plot with a "
                                   "cursor, contact points with their estimated forces, and a timeline to play and "
                                   "scrub. --serve shows it live on 127.0.0.1 instead (or as well). Needs viser "
                                   "(pip install 'bullet-dlo[view]').")
    s.add_argument("run", metavar="RUN", help="capture or rollout directory (one episode, see --episode), episode "
                   ".h5, grasp/render --series .npz or .h5, simulate --npz file, or a render output directory "
                   "(its final shape)")
    s.add_argument("--out", dest="page", metavar="PAGE.html", help="the page to write (a single .html file)")
    s.add_argument("--serve", action="store_true", help="serve the viewer live at http://127.0.0.1:PORT with a "
                   "row slider and play button, until Ctrl-C")
    s.add_argument("--port", type=int, default=None, help="port for --serve, 1024-65535 (default: a free one)")
    s.add_argument("--episode", type=int, default=None, metavar="K",
                   help="episode index in a capture or rollout directory (default: the first ok one)")
    s.add_argument("--scene", metavar="SCENE.yaml", help="the run's scene file: adds its obstacles and ground, its "
                   "cable (radius, and the model for contact forces of simulate results) and its arms' table")
    s.add_argument("--max-frames", type=int, default=400, metavar="N",
                   help="most rows in the page; longer runs are subsampled evenly (default 400)")
    s.set_defaults(func=cmd_view)
