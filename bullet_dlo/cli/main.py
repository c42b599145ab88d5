"""``bullet-dlo``: the command-line entry point, a parser that dispatches to one module per group.

simulate, stability, paper-table, convergence: :mod:`bullet_dlo.cli.simulate`; grasp, render:
:mod:`bullet_dlo.cli.robots`; capture, dataset: :mod:`bullet_dlo.cli.data`; resolve:
:mod:`bullet_dlo.cli.resolve`; bench: :mod:`bullet_dlo.cli.bench`.

Every invalid input ends with a one-line ``error: ...`` naming the bad key or option and
exit code 2, before any work starts: argparse's own errors too (:class:`Parser`), and output
paths are checked first (:func:`check_outputs`). A capture with failed episodes exits with 1. ``--quiet`` (before or after the command) leaves only results and errors: no
progress bars, no warnings, nothing from PyBullet's C code (see :mod:`bullet_dlo.cli.quiet`).
"""
from __future__ import annotations

import argparse
import contextlib
import re
import sys
import warnings
from typing import Any, Iterator, Sequence

from bullet_dlo.cli import data, fit, resolve, robots, simulate
from bullet_dlo.cli import validate
from bullet_dlo.cli import export
from bullet_dlo.cli import view
from bullet_dlo.cli import examples, warmup
from bullet_dlo._interrupt import is_command_line
from bullet_dlo.cli.quiet import flush_c_streams, quiet_output
from bullet_dlo.config.schema import output_dir, output_file
from bullet_dlo.core.validate import ParameterError

OUTPUT_FILES = ("json", "npz", "markdown", "series")
NEGATIVE_NUMBER = re.compile(r"^-(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$|^-(inf|infinity|nan)$", re.IGNORECASE)  # options naming a file the command writes


class Parser(argparse.ArgumentParser):
    """argparse with its errors on one line (``error: bullet-dlo simulate: argument --dt: ...``), exit 2.
    Subcommand parsers are of this class too (argparse makes them of the parent's class)."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        # values like -1e-3, -inf or -nan are numbers (argparse's own pattern takes them for options)
        self._negative_number_matcher = NEGATIVE_NUMBER

    def error(self, message: str):
        self.exit(2, f"error: {self.prog}: {message}\n")


def check_outputs(args: argparse.Namespace) -> None:
    """Every output path of the command, checked before it runs (a folder where a file is meant,
    a path under a file, a read-only location)."""
    for name in OUTPUT_FILES:
        if getattr(args, name, None):
            output_file(f"--{name}", getattr(args, name))
    if getattr(args, "out", None):
        output_dir("--out", args.out)

BENCH_COMMANDS = {
    "work-precision": "error vs wall time per simulated second for every integrator, dt, n, scenario S1-S4 and "
                      "engine; PNG + CSV",
    "stability": "largest stable dt vs E and n per method, measured by bisection, with the predicted limit",
    "peers": "PyElastica, MuJoCo and Newton on S1 and S2 next to ours (pip install '.[peers]')",
    "scaling": "cost of the implicit solve vs n up to 1000 and its fitted exponent",
    "resolve": "resolve's choices on S1-S4 checked against their references",
}


def cmd_bench(args: argparse.Namespace) -> int:
    from bullet_dlo.cli import bench

    return bench.run(args)


def _add_bench_parsers(sub) -> None:
    from bullet_dlo.cli import bench

    s = sub.add_parser("bench", help="speed against accuracy: work-precision, stability map, peers, scaling",
                       description="Benchmarks; each writes CSV/JSON and charts into --out.")
    bsub = s.add_subparsers(dest="bench_command", required=True, metavar="BENCH")
    for name, text in BENCH_COMMANDS.items():
        b = bsub.add_parser(name, help=text, description=text)
        bench.add_arguments(b)  # --out, --quick, --quiet
        b.set_defaults(func=cmd_bench)


def build_parser() -> argparse.ArgumentParser:
    """The whole command line (``bullet-dlo --help``; ``bullet-dlo COMMAND --help`` for each command)."""
    p = Parser(
        prog="bullet-dlo",
        description="Mass-spring-damper cables with stable integrators (PyBullet-free core), two robot arms "
                    "holding them, headless video and force datasets. All quantities in SI units.",
    )
    p.add_argument("-q", "--quiet", dest="quiet_all", action="store_true",
                   help="print only results and errors (no progress bars, warnings or PyBullet output); "
                        "also accepted after the command")
    common = Parser(add_help=False)
    common.add_argument("-q", "--quiet", action="store_true",
                        help="print only results and errors (no progress bars, warnings or PyBullet output)")
    sub = p.add_subparsers(dest="command", required=True, metavar="COMMAND")
    simulate.add_parsers(sub, common)
    robots.add_parsers(sub, common)
    data.add_parsers(sub, common)
    resolve.add_parsers(sub, common)
    fit.add_parsers(sub, common)
    validate.add_parsers(sub, common)
    export.add_parsers(sub, common)
    view.add_parsers(sub, common)
    examples.add_parsers(sub, common)
    warmup.add_parsers(sub, common)
    _add_bench_parsers(sub)
    return p


RUNS_KERNELS = {"simulate", "stability", "paper-table", "convergence", "grasp", "render", "capture", "rollouts",
                "resolve", "fit", "validate", "bench"}
"""Commands whose first run after an install compiles the Numba kernels."""


@contextlib.contextmanager
def compile_notice(args: argparse.Namespace) -> Iterator[None]:
    """One line on stderr when the command inside starts compiling the kernels (an empty cache), unless quiet.

    The line comes at Numba's first compile event, not before the command runs: bad input is then refused
    with its one error line (exit 2) before any kernel compiles, and nothing else."""
    from bullet_dlo._numba_cache import kernels_cold

    if args.quiet or args.command not in RUNS_KERNELS or not kernels_cold():
        yield
        return
    from numba.core import event

    class FirstCompile(event.Listener):
        told = False

        def on_start(self, ev: event.Event) -> None:
            if not self.told:
                self.told = True
                print("compiling the numerical kernels once (minutes after an install or upgrade; "
                      "cached afterwards, never counted in run times; `bullet-dlo warmup` does it ahead)",
                      file=sys.stderr)

        def on_end(self, ev: event.Event) -> None:
            pass

    listener = FirstCompile()
    event.register("numba:compile", listener)
    try:
        yield
    finally:
        event.unregister("numba:compile", listener)


def _reader_left() -> int:
    """stdout's reader closed the pipe (``bullet-dlo ... | head``): stop writing, as a shell tool does, with
    the exit status of SIGPIPE and no traceback."""
    import os

    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())  # Python's final flush of stdout then goes nowhere
    except (OSError, ValueError):
        pass
    return 141


@contextlib.contextmanager
def renamed_key_lines(enabled: bool) -> Iterator[None]:
    """Show each deprecated name a user's file or flag used (``cable.friction is deprecated; use
    cable.dynamic_friction ...``) as one ``warning:`` line on stderr, once; Python hides DeprecationWarnings
    outside ``__main__``, and these name a key the user wrote. A no-op when quiet."""
    if not enabled:
        yield
        return
    with warnings.catch_warnings():
        warnings.filterwarnings("default", message=r".* is deprecated; use ", category=DeprecationWarning)
        shown = warnings.showwarning

        def show(message: Any, category: type, *rest: Any, **kw: Any) -> None:
            if issubclass(category, DeprecationWarning) and " is deprecated; use " in str(message):
                print(f"warning: {message}", file=sys.stderr)
            else:
                shown(message, category, *rest, **kw)

        warnings.showwarning = show
        yield


STOPPED = (130, 143)
"""Exit codes of a command stopped by SIGINT (Ctrl-C) or SIGTERM."""


def main(argv: Sequence[str] | None = None) -> int:
    """Run the ``bullet-dlo`` command ``argv`` (default: the process's arguments); returns its exit code. The
    command line itself (not a library call) ends a stopped command at once: see :func:`end_stopped`."""
    code = run_command(argv)
    if code in STOPPED and is_command_line():
        end_stopped(code)
    return code


def end_stopped(code: int) -> None:
    """End the process with ``code`` now, without Python's teardown. A stopped command has closed its files and
    said what it kept; the teardown would only free memory, and after kernels compiled in this process (a cold
    Numba cache) it takes seconds: 4-5 s on an idle machine, 3.6 s beside another compile, for 10^6 objects and
    the compiled code's LLVM modules. A Ctrl-C then looked ignored."""
    import os

    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):  # a closed pipe or stream: nothing more can be said on it
            pass
    flush_c_streams()
    os._exit(code)


def run_command(argv: Sequence[str] | None = None) -> int:
    """The command ``argv``: its exit code (2 for a bad parameter, 130 for a Ctrl-C, 141 for a closed pipe)."""
    args = build_parser().parse_args(argv)
    args.quiet = bool(args.quiet_all or getattr(args, "quiet", False))
    try:
        with quiet_output(args.quiet), renamed_key_lines(not args.quiet):
            try:
                check_outputs(args)
                with compile_notice(args):
                    return int(args.func(args) or 0)
            except ParameterError as err:
                print(f"error: {err}", file=sys.stderr)
                return 2
            except KeyboardInterrupt:  # capture and rollouts report what they kept themselves; others stop here
                # on a line of its own (a progress bar may hold the current one); partial videos were removed
                print("\ninterrupted (Ctrl-C): stopped; files already completed are kept, partial ones removed",
                      file=sys.stderr)
                return 130
            except BrokenPipeError:
                return _reader_left()
    except BrokenPipeError:
        return _reader_left()


if __name__ == "__main__":
    sys.exit(main())
