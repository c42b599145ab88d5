"""A corpus of bad inputs for every subcommand, and the share that gets a clear exit-2 error.

Run ``python tests/cli/bad_inputs.py`` to print the figure (and each case that misses);
tests/cli/test_bad_input.py asserts it is 100 %. A case passes when ``bullet-dlo`` (called
in-process) exits with code 2 within ``TIMEOUT_S`` and prints exactly one line on stderr that
names the expected key or option and contains no traceback.
"""
from __future__ import annotations

import contextlib
import io
import signal
import sys
import tempfile
import traceback
from dataclasses import dataclass, field
from pathlib import Path

import yaml

TIMEOUT_S = 20

SCENE = {"cable": {"length": 0.3, "diameter": 0.004, "mass": 0.03, "youngs_modulus": 126e6, "n_masses": 5,
                   "damping": 0.01},
         "dt": 1e-3, "duration": 0.01}
SPEC = {"seed": 1, "episode": {"duration": 0.2, "record_rate": 60}, "camera": {"fps": 0}}


@dataclass
class Case:
    """argv (``{d}``: the case's temporary folder), files to write there, the word the error must name."""

    label: str
    argv: list[str]
    names: str
    files: dict[str, object] = field(default_factory=dict)  # name -> YAML data | str | bytes | DIR


DIR = object()


def with_key(base: dict, dotted: str, value: object) -> dict:
    """A deep copy of ``base`` with ``dotted`` (``a.b``) set to ``value`` (DELETE removes the key)."""
    out = yaml.safe_load(yaml.safe_dump(base))
    node = out
    *head, last = dotted.split(".")
    for k in head:
        if not isinstance(node.get(k), dict):
            node[k] = {}
        node = node[k]
    node[last] = value
    return out


INF, NAN = float("inf"), float("nan")

SCENE_VALUES = {
    "cable.length": [-1, 0, NAN, INF, "abc", [1], True, 1e-9, 1e9],
    "cable.diameter": [1.0, -0.004, NAN, "x"],
    "cable.mass": [0, -1, INF, "heavy"],
    "cable.youngs_modulus": [1e20, 0, -5, NAN, "abc"],
    "cable.n_masses": [8.4, True, 1e12, 1, "ten", 10.0000001],
    "cable.damping": [-1, NAN, INF, "x"],
    "cable.dynamic_friction": [-0.1, NAN, 0.5],  # (0.5: above the default static_friction, 0.3)
    "cable.static_friction": [-1, "x"],
    "cable.section": ["hexagon"],  # every closed set (bullet_dlo.core.enums) refuses a stranger, listing its names
    "cable.discretisation": ["fine"],
    "dt": [1e12, 0, -1, "abc", True, NAN, 0.5],
    "duration": [1e12, 0, -2, NAN, "long"],
    "newton.definite": ["abc", 2, NAN],
    "newton.max_iter": [0, 1e12, 2.5, "x"],
    "newton.tol": [-1, NAN, "x"],
    "newton.exact_from": [0, 1e12, 2.5, "x"],
    "detector.max_strain": [-1, "x", NAN],
    "detector.check_every": [0, 1.5, "x"],
    "detector.energy_factor": [0, INF],
    "bullet.ground": ["abc", -1, NAN, 2],
    "bullet.substeps": [0, 1e12, 2.5],
    "bullet.ground_height": [NAN, INF, "x"],
    "bullet.ground_friction": [-1, NAN],
    "bullet.self_collision": ["some"],
    "bullet.obstacles": ["box", [{"type": "sphere"}],
                         [{"type": "box", "half_extents": "abc", "position": [0, 0, 0]}],
                         [{"type": "box", "half_extents": [0.1, NAN, 0.1], "position": [0, 0, 0]}],
                         [{"type": "box", "half_extents": [0.1, 0.1, 0.1], "position": [0, 0, 0], "mass": -1}],
                         [{"type": "cylinder", "radius": 0, "height": 0.1, "position": [0, 0, 0]}],
                         [{"type": "box", "half_extents": [0.01] * 3, "position": [0, 0, -1]}] * 1001],  # over the cap
    "gravity": [[0, 0], [0, 0, INF], "down"],
    "layout.start": ["x", [1, 2]],
    "layout.direction": [[0, 0, 0]],
    "ends.first": ["glued"],
    "ends.last": ["welded"],
    "bullet.sync": ["never"],
    "tolerance.target": ["speed"],
    "arms.grip": ["glue"],
    "arms.payload": ["guess"],
    "arms.grip_static_friction": [NAN, -1],
    "arms.grip_dynamic_friction": [20],
    "motion": ["up", [{"end": "middle", "displacement": [0, 0, 0.01], "start": 0, "duration": 0.1}]],
    "initial": ["warm"],
    "integrator": ["foo"],
    "tolerance.value": [0, NAN],
}
SPEC_VALUES = {
    "camera.width": [0, NAN, INF, -3, 1e9, 2.5],
    "camera.height": [0, 1e9],
    "camera.fps": ["abc", None, [1, 2], INF, NAN, -1, 1e9],
    "camera": ["abc", 0, [1]],
    "episode": [5, 0, "x"],
    "episode.duration": [1e12, 0, NAN],
    "episode.record_rate": [0, INF, 1e12],
    "sample": [[1, 2], "x", {"grip": {"dist": "fixed", "value": "friction"},  # every draw of this fails after building
                             "integrator": {"dist": "choice", "values": ["symplectic_euler", "bdf2"]}}],
    "max_resamples": [NAN, -1, 0, 1e12, True],
    "seed": [True, -1, 1.5, "x", NAN, 2**70],
    "policy": ["maybe"],
    "resolve_tol": [0, NAN],
    "sample.n_masses": [{"dist": "choice", "values": [8.4, 10.6]}, {"dist": "fixed", "value": True}],
    "sample.length": [{"dist": "uniform", "low": 1, "high": 0.5}, {"dist": "normal", "mean": 0.3, "std": NAN}],
    "sample.speed": [{"dist": "log_uniform", "low": 0, "high": 1}],
    "sample.robot": [{"dist": "fixed", "value": "r2d2"}],
    "sample.foo": [1],
    "motion": [[{"type": "sine", "end": "last", "amplitude": [0, 0, 0.01], "frequency": -1}],
               [{"type": "sine", "end": "last", "frequency": {"dist": "uniform", "low": 1, "high": NAN}}],
               [{"type": "waypoints", "end": "first", "times": [0, 1], "displacements": [[0.01, 0, 0], [0, 0, 0]]}],
               [{"type": "wiggle", "end": "last"}], [], "x"],
    "sample.grip": [{"dist": "fixed", "value": "glue"}],
    "sample.section": [{"dist": "fixed", "value": "hexagon"}],
    "sample.integrator": [{"dist": "choice", "values": ["bdf2", "leapfrog"]}],
    "sample.dynamic_friction": [{"dist": "gaussian", "mean": 0.3, "std": 0.1}, {"dist": "uniform", "low": 0.1, "high": 0.4}],
    "sample.grip_dynamic_friction": [{"dist": "uniform", "low": 0.3, "high": 0.9}],
    "sample.grip_force": [{"dist": "fixed", "value": -2}],
}


def _scene_key_word(dotted: str) -> str:
    return dotted


def build_cases() -> list[Case]:
    """Every bad input of the corpus."""
    cases: list[Case] = []
    for key, values in SCENE_VALUES.items():
        for v in values:
            cmd = ["simulate", "{d}/s.yaml"] + (["--engine", "bullet"] if key.startswith("bullet") else [])
            cases.append(Case(f"scene {key}={v!r}", cmd, key.split(".")[0] if key == "motion" else key,
                              {"s.yaml": with_key(SCENE, key, v)}))
    for key, values in SPEC_VALUES.items():
        for v in values:
            cases.append(Case(f"spec {key}={v!r}", ["capture", "{d}/c.yaml", "--out", "{d}/out", "--episodes", "2"],
                              key, {"c.yaml": with_key(SPEC, key, v)}))
    # files that are no scene / spec at all, for every file-taking command
    file_commands = {
        "simulate": ["simulate", "{d}/f"], "stability": ["stability", "{d}/f"], "resolve": ["resolve", "{d}/f"],
        "render": ["render", "{d}/f", "--out", "{d}/r"], "grasp": ["grasp", "--scene", "{d}/f"],
        "capture": ["capture", "{d}/f", "--out", "{d}/out", "--episodes", "1"],
    }
    bad_files = {"non-UTF-8": b"cable: {length: \xff\xfe}\n", "invalid YAML": "cable: [1, 2\n",
                 "python tag": "cable: !!python/object/apply:os.system ['true']\n", "a list": "- 1\n- 2\n",
                 "a scalar": "42\n", "directory": DIR}
    for cmd, argv in file_commands.items():
        for what, content in bad_files.items():
            cases.append(Case(f"{cmd} with {what}", argv, "{d}/f", {"f": content}))
        cases.append(Case(f"{cmd} with a missing file", argv, "{d}/f"))
    # flags
    scene = {"s.yaml": SCENE}
    flag_cases = [
        (["simulate", "{d}/s.yaml", "--dt", v], "--dt") for v in ("0", "nan", "inf", "-1", "1e12", "abc")
    ] + [
        (["simulate", "{d}/s.yaml", "--duration", v], "--duration") for v in ("1e12", "nan", "0", "-inf")
    ] + [
        (["simulate", "{d}/s.yaml", "--dt", "1e-12", "--duration", "1"], "steps"),
        (["simulate", "{d}/s.yaml", "--integrator", "foo"], "integrator"),
        (["simulate", "{d}/s.yaml", "--json", "{d}"], "--json"),
        (["simulate", "{d}/s.yaml", "--json", "{d}/s.yaml/out.json"], "--json"),
        (["simulate", "{d}/s.yaml", "--json", "/proc/bullet_dlo/out.json"], "--json"),
        (["simulate", "{d}/s.yaml", "--npz", "{d}"], "--npz"),
        (["simulate", "{d}/s.yaml", "--engine", "ode"], "--engine"),
        (["stability", "{d}/s.yaml", "--json", "{d}"], "--json"),
        (["grasp", "--dt", "1e12"], "--dt"),
        (["grasp", "--dt", "0"], "--dt"),
        (["grasp", "--dt", "nan"], "--dt"),
        (["grasp", "--duration", "1e12"], "--duration"),
        (["grasp", "--duration", "nan"], "--duration"),
        (["grasp", "--noise", "1e12"], "--noise"),
        (["grasp", "--noise", "-1"], "--noise"),
        (["grasp", "--noise", "nan"], "--noise"),
        (["grasp", "--sensor-rate", "-1"], "--sensor-rate"),
        (["grasp", "--sensor-rate", "nan"], "--sensor-rate"),
        (["grasp", "--robot", "r2d2"], "robot"),
        (["grasp", "--json", "{d}"], "--json"),
        (["render", "{d}/s.yaml", "--out", "{d}/s.yaml"], "--out"),
        (["render", "{d}/s.yaml", "--out", "{d}/s.yaml/sub"], "--out"),
        (["render", "{d}/s.yaml", "--out", "/proc/bullet_dlo"], "--out"),
        (["render", "{d}/s.yaml", "--out", "{d}/r", "--fps", "0"], "--fps"),
        (["render", "{d}/s.yaml", "--out", "{d}/r", "--fps", "nan"], "--fps"),
        (["render", "{d}/s.yaml", "--out", "{d}/r", "--fps", "inf"], "--fps"),
        (["render", "{d}/s.yaml", "--out", "{d}/r", "--width", "0"], "--width"),
        (["render", "{d}/s.yaml", "--out", "{d}/r", "--height", "-5"], "--height"),
        (["render", "{d}/s.yaml", "--out", "{d}/r", "--width", "100000"], "--width"),
        (["render", "{d}/s.yaml", "--out", "{d}/r", "--robot", "r2d2"], "robot"),
        (["paper-table", "--steps", "0"], "--steps"),
        (["paper-table", "--steps", "nan"], "--steps"),
        (["paper-table", "--steps", "1e-12"], "steps"),
        (["paper-table", "--masses", "0"], "--masses"),
        (["paper-table", "--masses", "1000000000"], "--masses"),
        (["paper-table", "--moduli", "-1"], "--moduli"),
        (["paper-table", "--moduli", "nan"], "--moduli"),
        (["paper-table", "--damping", "nan"], "--damping"),
        (["paper-table", "--damping", "-1"], "--damping"),
        (["paper-table", "--duration", "0"], "--duration"),
        (["paper-table", "--duration", "1e12"], "--duration"),
        (["paper-table", "--tables", "rates", "--rate-duration", "1e12"], "--rate-duration"),
        (["paper-table", "--tables", "rates", "--rate-duration", "nan"], "--rate-duration"),
        (["paper-table", "--integrators", "foo"], "integrator"),
        (["paper-table", "--markdown", "{d}"], "--markdown"),
        (["paper-table", "--tables", "nope"], "--tables"),
        (["convergence", "--masses", "0"], "--masses"),
        (["convergence", "--masses", "1000000000"], "--masses"),
        (["convergence", "--json", "{d}"], "--json"),
        (["resolve", "{d}/s.yaml", "--tol", "0"], "--tol"),
        (["resolve", "{d}/s.yaml", "--tol", "nan"], "--tol"),
        (["resolve", "{d}/s.yaml", "--tol", "5"], "--tol"),
        (["resolve", "{d}/s.yaml", "--rollout", "nan"], "--rollout"),
        (["resolve", "{d}/s.yaml", "--rollout", "0"], "--rollout"),
        (["resolve", "{d}/s.yaml", "--rollout", "1e12"], "--rollout"),
        (["resolve", "{d}/s.yaml", "--json", "{d}"], "--json"),
        (["capture", "{d}/c.yaml", "--out", "{d}/out", "--episodes", "1000000000000"], "--episodes"),
        (["capture", "{d}/c.yaml", "--out", "{d}/out", "--episodes", "0"], "--episodes"),
        (["capture", "{d}/c.yaml", "--out", "{d}/out", "--episodes", "-3"], "--episodes"),
        (["capture", "{d}/c.yaml", "--out", "{d}/out", "--episodes", "2", "--workers", "1000000000000"], "--workers"),
        (["capture", "{d}/c.yaml", "--out", "{d}/out", "--episodes", "2", "--workers", "0"], "--workers"),
        (["capture", "{d}/c.yaml", "--out", "{d}/c.yaml", "--episodes", "2"], "--out"),
        (["capture", "{d}/c.yaml", "--out", "{d}/c.yaml/sub", "--episodes", "2"], "--out"),
        (["capture", "{d}/c.yaml", "--out", "/proc/bullet_dlo", "--episodes", "2"], "--out"),
        (["dataset", "summary", "{d}"], "capture directory"),
        (["dataset", "summary", "{d}/c.yaml"], "capture directory"),
        (["dataset", "summary", "{d}/nothing"], "capture directory"),
        (["bench", "stability", "--out", "{d}/c.yaml"], "--out"),
        (["rollouts", "CartPole-v1", "--out", "{d}/ro", "--episodes", "1"], "CartPole-v1"),  # no cable, no sensors
        (["rollouts", "bullet_dlo/Nope-v0", "--out", "{d}/ro", "--episodes", "1"], "Nope-v0"),
    ]
    for argv, names in flag_cases:
        cases.append(Case(" ".join(argv[:1] + argv[2:] if argv[0] != "dataset" else argv), argv, names,
                          {**scene, "c.yaml": SPEC}))
    # damaged capture directories given to dataset summary
    good_json = '{"digest": "44136fa355b3678a", "spec": {}, "version": "0"}'  # the digest of {} (checked on read)
    damaged = {
        "garbage manifest": "not json at all\n{\"episode\": \n",
        "manifest of non-records": "[1, 2]\n\"text\"\n",
        "manifest records without keys": '{"episode": "a"}\n{"status": "ok"}\n',
    }
    for what, text in damaged.items():
        cases.append(Case(f"dataset summary, {what}", ["dataset", "summary", "{d}/cap"], "manifest",
                          {"cap/capture.json": good_json, "cap/manifest.jsonl": text}))
    cases.append(Case("dataset summary, capture.json not JSON", ["dataset", "summary", "{d}/cap"], "capture.json",
                      {"cap/capture.json": "{\"digest\": ", "cap/manifest.jsonl": ""}))
    # view: runs that are not there or not runs, pages that are not .html
    cases += [Case("view, missing run", ["view", "{d}/none.npz", "--out", "{d}/v.html"], "none.npz"),
              Case("view, not an npz", ["view", "{d}/r.npz", "--out", "{d}/v.html"], "r.npz", {"r.npz": "text"}),
              Case("view, page not .html", ["view", "{d}/r.npz", "--out", "{d}/v.png"], "--out", {"r.npz": "text"}),
              Case("view, no output", ["view", "{d}/r.npz"], "--serve", {"r.npz": "text"}),
              Case("view, folder of nothing", ["view", "{d}/f", "--out", "{d}/v.html"], "capture", {"f": DIR}),
              Case("view, negative --max-frames", ["view", "{d}/r.npz", "--out", "{d}/v.html", "--max-frames", "-1"],
                   "--max-frames", {"r.npz": "text"})]
    # validate beam's numeric options: checked before any file is read (a tiny --dt ran for ever, a huge one or an
    # E of 1e300 ended in a traceback)
    beam = ["validate", "beam", "{d}/f", "{d}/p", "--json", "{d}/o.json"]
    for option, value in (("--dt", "1e-12"), ("--dt", "1e9"), ("--youngs-modulus", "1e300"),
                          ("--n-masses", "100000000"), ("--knot-step", "1e9"), ("--density", "nan"),
                          ("--filter-cutoff", "1e6")):
        cases.append(Case(f"validate beam {option} {value}", beam + [option, value], option, {"f": DIR, "p": DIR}))
    cases += [Case("validate deform --dt 1e-12", ["validate", "deform", "{d}/dlo", "--json", "{d}/o.json", "--dt",
                                                  "1e-12"], "--dt", {"dlo": DIR}),
              Case("validate deform --max-train-trials 1", ["validate", "deform", "{d}/dlo", "--json", "{d}/o.json",
                                                            "--max-train-trials", "1"], "--max-train-trials",
                   {"dlo": DIR})]
    cases += [Case("examples, under a file", ["examples", "{d}/f/sub"], "DIR", {"f": "text"}),
              Case("fit, band reversed", ["fit", "{d}/r.csv", "--length", "0.3", "--diameter", "0.004", "--band", "8",
                                          "1.5", "--out", "{d}/o"], "--band", {"r.csv": "t\n0\n"}),
              Case("fit, beam step 0", ["fit", "{d}/r.csv", "--length", "0.3", "--diameter", "0.004", "--beam-step",
                                        "0", "--out", "{d}/o"], "--beam-step", {"r.csv": "t\n0\n"}),
              Case("fit, stiffness grid over 101", ["fit", "{d}/r.csv", "--length", "0.3", "--diameter", "0.004",
                                                    "--stiffness-grid", "500", "--out", "{d}/o"], "--stiffness-grid",
                   {"r.csv": "t\n0\n"}),
              Case("fit, pickle that is not a trial", ["fit", "{d}/t.pkl", "--diameter", "0.01", "--mass", "0.05",
                                                       "--out", "{d}/o"], "t.pkl", {"t.pkl": "not a pickle"})]
    return cases


@dataclass
class Outcome:
    case: Case
    code: int | None
    stderr: str
    ok: bool
    why: str


class _Timeout(Exception):
    pass


def _alarm(signum, frame):
    raise _Timeout()


def run_case(case: Case, root: Path) -> Outcome:
    """Run one case in-process in a fresh folder under ``root``."""
    from bullet_dlo.cli.main import main

    d = Path(tempfile.mkdtemp(dir=root))
    for name, content in case.files.items():
        path = d / name
        path.parent.mkdir(parents=True, exist_ok=True)
        if content is DIR:
            path.mkdir()
        elif isinstance(content, bytes):
            path.write_bytes(content)
        elif isinstance(content, str):
            path.write_text(content)
        else:
            path.write_text(yaml.safe_dump(content))
    argv = [a.replace("{d}", str(d)) for a in case.argv]
    err, out = io.StringIO(), io.StringIO()
    code: int | None = None
    old = signal.signal(signal.SIGALRM, _alarm)
    signal.alarm(TIMEOUT_S)
    try:
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out):
            try:
                code = main(argv)
            except SystemExit as exc:
                code = exc.code if isinstance(exc.code, int) else 1
    except _Timeout:
        return Outcome(case, None, err.getvalue(), False, f"no answer within {TIMEOUT_S} s")
    except BaseException:  # noqa: BLE001 - a traceback is what we count
        return Outcome(case, None, err.getvalue(), False, "traceback: " + traceback.format_exc(limit=-2)[-300:])
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)
    text = err.getvalue()
    lines = [ln for ln in text.splitlines() if ln.strip()]
    if code != 2:
        return Outcome(case, code, text, False, f"exit code {code}")
    if "Traceback" in text:
        return Outcome(case, code, text, False, "traceback on stderr")
    if len(lines) != 1:
        return Outcome(case, code, text, False, f"{len(lines)} lines on stderr")
    if case.names.replace("{d}", str(d)).lower() not in lines[0].lower():
        return Outcome(case, code, text, False, f"does not name {case.names!r}")
    return Outcome(case, code, text, True, "")


def measure(cases: list[Case] | None = None) -> list[Outcome]:
    """Run every case; returns the outcomes."""
    cases = build_cases() if cases is None else cases
    with tempfile.TemporaryDirectory() as root:
        return [run_case(c, Path(root)) for c in cases]


if __name__ == "__main__":
    outcomes = measure()
    bad = [o for o in outcomes if not o.ok]
    for o in bad:
        print(f"MISS {o.case.label}: {o.why}\n     {o.stderr.strip()[:300]!r}")
    good = len(outcomes) - len(bad)
    print(f"{good} / {len(outcomes)} bad inputs get a clear exit-2 error ({100 * good / len(outcomes):.1f} %)")
    sys.exit(0 if not bad else 1)
