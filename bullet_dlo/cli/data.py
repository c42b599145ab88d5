"""``bullet-dlo capture | rollouts | dataset summary | dataset verify``: domain-randomised force datasets
and policy rollouts.

``capture`` and ``rollouts`` stop on SIGINT/SIGTERM with one line and exit status 130/143, having
recorded what finished; a write failure (full disk, read-only folder) is one line and exit 1.
``dataset verify`` and ``dataset summary`` name every missing, damaged, foreign, swapped or
non-finite episode file, and every planned episode without a record (an incomplete capture), and
exit 1 with their count.
"""
from __future__ import annotations

import argparse
import signal
import sys
import threading
from pathlib import Path

from bullet_dlo.cli.simulate import write_json
from bullet_dlo.core.validate import ParameterError


class _EarlyStop(threading.Event):
    """Set by SIGINT/SIGTERM from the command's first line on (``signum``: which); duck-types
    :class:`bullet_dlo.data.capture.StopSignal`, which is not imported yet when it is installed.
    With ``raising`` True (around calls that may block, such as reading the spec) the signal also
    raises KeyboardInterrupt; a second signal always does (a stop that is not obeyed is forced)."""

    signum: int = 0
    raising: bool = False


def _install_stop() -> tuple[_EarlyStop, dict]:
    """SIGINT and SIGTERM set the returned event instead of raising inside an import (which may
    swallow a KeyboardInterrupt); returns it and the previous handlers."""
    stop = _EarlyStop()

    def handler(signum: int, _frame) -> None:
        again = stop.is_set()
        stop.signum = signum
        stop.set()
        if stop.raising or again:
            raise KeyboardInterrupt

    if threading.current_thread() is not threading.main_thread():
        return stop, {}
    return stop, {s: signal.signal(s, handler) for s in (signal.SIGINT, signal.SIGTERM)}


def _restore(previous: dict) -> None:
    for s, h in previous.items():
        signal.signal(s, h)


def _stopped(signum: int, what: str) -> int:
    """One line for a command stopped by ``signum``; its exit status 128 + signum."""
    signum = signum or signal.SIGINT
    print(f"error: interrupted by {signal.Signals(signum).name}: {what}", file=sys.stderr)
    return 128 + signum


def cmd_capture(args: argparse.Namespace) -> int:
    stop, previous = _install_stop()  # before the slow imports: a Ctrl-C during them is not lost
    try:
        return _capture(args, stop)
    finally:
        _restore(previous)


def _capture(args: argparse.Namespace, stop) -> int:
    """``capture`` with its stop event installed."""
    from bullet_dlo.config.capture import CaptureSpec
    from bullet_dlo.data import capture
    from bullet_dlo.data.capture import CaptureInterrupted
    from bullet_dlo.data.safeio import StorageError

    if stop.is_set():
        return _stopped(stop.signum, "nothing was captured")
    try:
        stop.raising = True  # reading the spec may block (a FIFO): a signal interrupts it
        spec = CaptureSpec.from_yaml(args.spec)
        stop.raising = False  # from here the coordinator stops at its own pace, recording what finished
        res = capture(spec, args.out, args.episodes, workers=args.workers, backend=args.backend,
                      resume=args.resume, progress=not args.quiet, stop=stop)
    except CaptureInterrupted as err:
        return _stopped(err.signum, str(err).split(": ", 1)[1])
    except KeyboardInterrupt:
        return _stopped(stop.signum, f"stopped at once; episodes finished before are recorded in {args.out}; "
                        "bullet-dlo capture ... --resume continues")
    except StorageError as err:
        print(f"error: {err}", file=sys.stderr)
        return 1
    for name in res.rerun_damaged:
        print(f"re-ran {name}")
    print(f"{res.done} episodes in {res.out} ({res.flagged} flagged: unstable or failing a quality limit, "
          f"{res.failed} failed); ran {res.ran} "
          f"in {res.wall_time_s:.1f} s = {res.episodes_per_second:.2f} episodes/s with {args.workers} worker(s)")
    planned = _planned(res.out)
    if planned is not None and planned > args.episodes:  # (a directory's plan grows, never shrinks)
        print(f"note: {res.out} plans {planned} episodes (an earlier capture asked for them); this one made sure of "
              f"the first {args.episodes}: --episodes {planned} --resume completes it")
    if res.complete:
        return 0
    lost = [f"{len(res.failed_episodes)} of {args.episodes} episodes failed ({_first(res.failed_episodes)}; "
            "errors in manifest.jsonl)"] if res.failed_episodes else []
    lost += [f"{len(res.missing_episodes)} have no record ({_first(res.missing_episodes)})"] \
        if res.missing_episodes else []
    print(f"error: {'; '.join(lost)}; bullet-dlo capture ... --resume re-runs them", file=sys.stderr)
    return 1


def cmd_rollouts(args: argparse.Namespace) -> int:
    """``rollouts``: in this process, episode by episode; SIGINT/SIGTERM raise KeyboardInterrupt once
    the imports are done (an import may swallow it), between or inside episodes: the finished
    ones are recorded, the one running is re-run by ``--resume``."""
    stop, previous = _install_stop()
    try:
        from bullet_dlo.core.validate import check_int
        from bullet_dlo.data.safeio import StorageError
        from bullet_dlo.envs.rollouts import record_rollouts

        if stop.is_set():
            return _stopped(stop.signum, "nothing was recorded")

        def interrupt(signum: int, _frame) -> None:
            stop.signum = signum
            raise KeyboardInterrupt

        if previous:
            for s in previous:
                signal.signal(s, interrupt)
        kwargs = {} if args.max_steps is None else {"max_episode_steps": check_int("--max-steps", args.max_steps,
                                                                                    1, 1_000_000)}
        try:
            res = record_rollouts(args.env, args.policy, args.out, args.episodes, seed=args.seed,
                                  record_rate=args.record_rate, env_kwargs=kwargs, resume=args.resume,
                                  progress=not args.quiet)
        except KeyboardInterrupt:
            return _stopped(stop.signum, f"the rollouts finished before it are recorded in {args.out}; "
                            "bullet-dlo rollouts ... --resume continues")
        except StorageError as err:
            print(f"error: {err} (bullet-dlo rollouts ... --resume continues)", file=sys.stderr)
            return 1
    finally:
        _restore(previous)
    print(f"{res.done} rollouts of {args.policy} in {res.out} ({res.flagged} flagged, {res.failed} failed); "
          f"ran {res.ran} in {res.wall_time_s:.1f} s")
    if res.complete:
        return 0
    print(f"error: {len(res.failed_episodes)} of {args.episodes} rollouts failed ({_first(res.failed_episodes)}; "
          "errors in manifest.jsonl); bullet-dlo rollouts ... --resume re-runs them", file=sys.stderr)
    return 1


def _first(indices: tuple[int, ...], count: int = 10) -> str:
    """``episodes 3, 5, 9`` (the first ``count`` of them)."""
    more = f", ... (+{len(indices) - count})" if len(indices) > count else ""
    return "episodes " + ", ".join(map(str, indices[:count])) + more


def _verified(directory: str):
    """The dataset in ``directory`` and its full verification report, printed when not clean."""
    from bullet_dlo.data import Dataset

    ds = Dataset(directory, check=False)
    report = ds.verify()
    return ds, report


def _verify_failed(report, directory: str) -> int:
    """Print the problems of ``report`` and its count line; exit status 1."""
    for line in report.lines():
        print(line)
    what = []
    if report.problems:
        what.append(f"{len(report.problems)} of {report.checked} recorded episodes in {directory} failed "
                    "verification (missing, damaged, foreign, swapped or non-finite)")
    if report.missing:
        what.append(f"{directory} is {report.incomplete()}")
    print(f"error: {'; '.join(what)}; bullet-dlo {_maker(directory)} ... --resume re-runs them", file=sys.stderr)
    return 1


def _spec_of(directory) -> dict:
    """The spec a capture or rollouts directory was made with (empty when it has none or it is damaged)."""
    from bullet_dlo.data.storage import read_spec_file

    try:
        return read_spec_file(Path(directory))
    except ParameterError:
        return {}


def _maker(directory) -> str:
    """The command that makes ``directory``: ``rollouts`` for a rollouts directory, else ``capture``."""
    return "rollouts" if "rollout" in _spec_of(directory).get("spec", {}) else "capture"


def _planned(directory) -> int | None:
    """The episode count a capture directory plans (None: unknown)."""
    return _spec_of(directory).get("episodes")


def cmd_dataset_verify(args: argparse.Namespace) -> int:
    """``dataset verify DIR``: every recorded episode file against its manifest line, nothing else."""
    _, report = _verified(args.dir)
    if not report.ok:
        return _verify_failed(report, args.dir)
    plan = f" (of {report.planned} planned, none missing)" if report.planned is not None else ""
    print(f"{report.checked} recorded episodes{plan} in {args.dir}: {report.hashed} verified by sha256, "
          f"{report.unhashed} without a recorded hash; no problems")
    for line in report.lines():
        print(line)
    return 0


def cmd_dataset_summary(args: argparse.Namespace) -> int:
    from bullet_dlo.data.reader import JOINT_REACTION_RATE
    from bullet_dlo.data.safeio import StorageError

    png = Path(args.dir) / "quality.png"
    ds, report = _verified(args.dir)
    try:
        summary = ds.summary(png)
    except StorageError as err:
        print(f"error: {err}", file=sys.stderr)
        return 1
    print(f"{summary['episodes']} episodes: {summary['ok']} ok, {summary['flagged']} flagged "
          f"({summary['flagged_for_quality']} for force quality), "
          f"{summary['failed']} failed; stability decisions: {summary['decisions']}")
    for run in summary["flagged_runs"]:
        if run["time_to_instability"] is not None:
            print(f"  flagged: episode {run['episode']} unstable at t = {run['time_to_instability']} s")
        else:
            print(f"  flagged: episode {run['episode']}: {run['reason']}")
    for key, (lo, hi) in sorted(summary["coverage"].items()):
        print(f"  {key:16s} {lo:.4g} .. {hi:.4g}")
    old = summary["old_tare_tilted"]
    if old:
        print(f"WARNING: {len(old)} of them ({_first(tuple(old))}) were recorded before payload compensation (bullet_dlo "
              f"< 0.3) and their grippers tilted: their wrist forces hold the hand's weight seen from the turned "
              f"sensor (up to tens of cable weights); re-capture them")
    turned = summary["joint_reaction_turned"]
    if turned:
        print(f"WARNING: {len(turned)} of them ({_first(tuple(turned))}) took their wrist forces from Bullet's joint "
              f"reaction (recorded before sensor_transmitted) while a gripper turned faster than "
              f"{JOINT_REACTION_RATE} rad/s: the reaction is off by a load growing as the turn rate squared; "
              f"re-capture them")
    print(f"quality histogram: {png}")
    if args.json:
        write_json(args.json, summary | {"verification": {"checked": report.checked, "hashed": report.hashed,
                                                          "unhashed": report.unhashed,
                                                          "problems": [str(p) for p in report.problems],
                                                          "planned": report.planned,
                                                          "missing": report.missing}})
    if not report.ok:
        return _verify_failed(report, args.dir)
    for line in report.lines():
        print(line)
    return 0


def add_parsers(sub, common: argparse.ArgumentParser) -> None:
    """``capture`` and ``dataset`` on ``sub`` (argparse subparsers); ``common``: shared options."""
    s = sub.add_parser("capture", parents=[common], help="capture a domain-randomised dual-arm force dataset",
                       description="Run episodes 0..N-1 of SPEC.yaml (see demos/specs/dr_small.yaml) into DIR: one "
                                   "HDF5 file per episode, manifest.jsonl, capture.json; a progress bar with ETA "
                                   "on stderr.")
    s.add_argument("spec", help="randomisation spec (YAML)")
    s.add_argument("--out", required=True, metavar="DIR", help="capture directory")
    s.add_argument("--episodes", type=int, required=True, help="number of episodes N")
    s.add_argument("--workers", type=int, default=1, help="parallel worker processes (default 1)")
    s.add_argument("--backend", default="local", choices=["local", "ray"],
                   help="local process pool (default) or a Ray cluster (RAY_ADDRESS, else a local Ray instance)")
    s.add_argument("--resume", action="store_true", help="continue an interrupted capture in DIR")
    s.set_defaults(func=cmd_capture)

    s = sub.add_parser("rollouts", parents=[common], help="record policy rollouts of an environment as a dataset",
                       description="Run a policy in a bullet_dlo Gymnasium environment for N episodes (reset seeds "
                                   "SEED, SEED+1, ...) and write them into DIR in the dataset's episode format "
                                   "(the capture's columns plus actions, rewards and observations), readable by "
                                   "'dataset summary' and 'fit'.")
    s.add_argument("env", help="environment id, e.g. bullet_dlo/TensionTracking-v0")
    s.add_argument("--policy", default="scripted",
                   help="random | scripted (the environment's scripted controller) | zero | package.module:function "
                        "(a callable obs -> action); default scripted")
    s.add_argument("--out", required=True, metavar="DIR", help="rollout directory")
    s.add_argument("--episodes", type=int, required=True, help="number of episodes N")
    s.add_argument("--seed", type=int, default=0, help="reset seed of episode 0 (episode i: SEED + i); default 0")
    s.add_argument("--record-rate", type=float, default=120.0, help="rate [Hz] of the recorded physics rows "
                   "(default 120; control steps are always all recorded)")
    s.add_argument("--max-steps", type=int, default=None, help="episode length in control steps (default: the "
                   "environment's registered limit)")
    s.add_argument("--resume", action="store_true", help="continue an interrupted recording in DIR")
    s.set_defaults(func=cmd_rollouts)

    s = sub.add_parser("dataset", parents=[common], help="inspect a captured dataset",
                       description="Inspect a capture directory written by bullet-dlo capture.")
    dsub = s.add_subparsers(dest="dataset_command", required=True, metavar="ACTION")
    d = dsub.add_parser("summary", parents=[common], help="counts, flagged runs, parameter coverage, quality "
                        "histogram (PNG)", description="Counts, flagged runs, parameter coverage and a quality "
                        "histogram (DIR/quality.png) of a capture directory.")
    d.add_argument("dir", help="capture directory")
    d.add_argument("--json", metavar="OUT.json", help="write the summary as JSON")
    d.set_defaults(func=cmd_dataset_summary)
    d = dsub.add_parser("verify", parents=[common], help="check every episode file against its manifest line",
                        description="Check every recorded episode file of DIR against its manifest line (size, "
                                    "sha256, episode number, spec): name each missing, damaged (truncated, "
                                    "changed, a link, a directory, a FIFO), foreign or swapped one; exit 1 with "
                                    "their count. Old lines without a hash are checked as far as they can be.")
    d.add_argument("dir", help="capture directory")
    d.set_defaults(func=cmd_dataset_verify)
