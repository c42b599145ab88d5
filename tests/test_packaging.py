"""The package as a user gets it: the wheel's contents, a non-editable install used from another
directory, robots that load wherever they are installed, and the 0.1 module paths.

The wheel is built from a copy of the sources (``python -m build --no-isolation``: no network,
no ``build/`` folder left in the repository) and installed with ``--no-deps`` into a fresh
virtual environment that sees the test environment's packages (``--system-site-packages``,
plus a ``.pth`` bridge for when the tests themselves run in a venv). The grasps run there
with ``NUMBA_DISABLE_JIT=1``: a new install path has no Numba cache, and compiling every
kernel afresh takes one to two minutes; the kernels are the ones the rest of the suite
compiles and tests, and what is at stake here is which files the wheel holds and finds.
"""
from __future__ import annotations

import json
import os
import shutil
import site
import subprocess
import sys
import tempfile
import warnings
import zipfile
from pathlib import Path

import pybullet as pb
import pybullet_data
import pytest
import yourdfpy

from bullet_dlo.config.robot import load_robot_spec
from bullet_dlo.robots import compose

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib

ROOT = Path(__file__).resolve().parents[1]
PROJECT = tomllib.loads((ROOT / "pyproject.toml").read_text())
VERSION = PROJECT["project"]["version"]
ROBOTS = ("kuka", "panda")
OLD_PATHS = ("params", "forces", "linalg", "model", "boundary", "integrators", "stability", "statics", "validation",
             "paper", "resolve", "scene", "randomization", "bullet_scene", "bullet_cable", "sensors", "dual_arm",
             "video", "recording", "dataset", "peers", "bench_cli")  # 0.1 modules; robots, render, bench, cli
NOW_SUBPACKAGES = ("robots", "render", "bench", "cli")            # are subpackages of the same name now


def run(args: list[str | Path], cwd: Path = ROOT, env: dict | None = None, timeout: float = 300.0) -> str:
    """Run a command; its stdout, or an assertion error with everything it printed."""
    proc = subprocess.run([str(a) for a in args], cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout)
    assert proc.returncode == 0, f"{' '.join(map(str, args))} failed:\n{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}"
    return proc.stdout


def package_dirs(root: Path) -> set[str]:
    """Dotted names of the folders of ``root/bullet_dlo`` that hold Python files."""
    return {".".join(p.parent.relative_to(root).parts) for p in (root / "bullet_dlo").rglob("*.py")
            if not any(part.startswith((".", "__pycache__")) for part in p.parts)}


def link_tree(src: Path, dst: Path) -> None:
    """Copy a folder as hard links where the file system allows it (the arm meshes are megabytes)."""
    def link_or_copy(a: str, b: str) -> None:
        try:
            os.link(a, b)
        except OSError:
            shutil.copy2(a, b)
    shutil.copytree(src, dst, copy_function=link_or_copy)


@pytest.fixture(scope="module")
def sources(tmp_path_factory) -> Path:
    """What a clean checkout holds for the build: the package, the asset folders, pyproject.toml, README.md."""
    src = tmp_path_factory.mktemp("src")
    for name in ("bullet_dlo", "robots", "urdf", "demos/scenes", "demos/specs"):
        shutil.copytree(ROOT / name, src / name, ignore=shutil.ignore_patterns("__pycache__", ".*", "*.egg-info"))
    for name in ("pyproject.toml", "README.md"):
        shutil.copy2(ROOT / name, src / name)
    return src


@pytest.fixture(scope="module")
def wheel(sources, tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("dist")
    run([sys.executable, "-m", "build", "--wheel", "--no-isolation", "--outdir", out, sources], timeout=180)
    (built,) = out.glob("*.whl")
    return built


@pytest.fixture(scope="module")
def venv(wheel, tmp_path_factory) -> Path:
    """A fresh virtual environment with the wheel installed (not editable); the dependencies are the test env's."""
    env_dir = tmp_path_factory.mktemp("venv")
    run([sys.executable, "-m", "venv", "--system-site-packages", "--without-pip", env_dir])
    python = env_dir / "bin" / "python"
    purelib = Path(run([python, "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"]).strip())
    bridge = "".join(f"import site; site.addsitedir({d!r})\n" for d in site.getsitepackages())
    (purelib / "zz_test_environment.pth").write_text(bridge)  # after the venv's own packages on sys.path
    run([python, "-m", "pip", "install", "--no-deps", "--no-index", "--quiet", wheel])
    return env_dir


def clean_env(**extra: str) -> dict[str, str]:
    """This process's environment without anything that would put the source tree on the path."""
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME", "PYTHONSTARTUP")}
    return {**env, **extra}


def test_every_package_folder_is_listed_for_the_wheel():
    listed = set(PROJECT["tool"]["setuptools"]["packages"])
    missing = package_dirs(ROOT) - listed
    assert missing == set(), f"add {sorted(missing)} to [tool.setuptools] packages in pyproject.toml"
    mapped = PROJECT["tool"]["setuptools"]["package-dir"]
    assert mapped == {"bullet_dlo._assets.robots": "robots", "bullet_dlo._assets.urdf": "urdf",
                      "bullet_dlo._assets.scenes": "demos/scenes", "bullet_dlo._assets.specs": "demos/specs"}
    assert set(mapped) <= listed


def test_version_is_the_project_version():
    import bullet_dlo

    assert bullet_dlo.__version__ == VERSION


def test_wheel_holds_every_module_and_the_robot_assets(wheel, sources):
    assert wheel.name == f"bullet_dlo-{VERSION}-py3-none-any.whl"
    names = set(zipfile.ZipFile(wheel).namelist())
    modules = {p.relative_to(sources).as_posix() for p in (sources / "bullet_dlo").rglob("*.py")}
    assert modules - names == set()
    assert {f"{pkg.replace('.', '/')}/__init__.py" for pkg in package_dirs(sources)} <= names
    assets = ({f"bullet_dlo/_assets/robots/{p.name}" for p in (sources / "robots").glob("*.yaml")}
              | {f"bullet_dlo/_assets/urdf/{p.name}" for p in (sources / "urdf").glob("*.urdf")}
              | {f"bullet_dlo/_assets/{k}/{p.name}" for k in ("scenes", "specs")
                 for p in (sources / "demos" / k).glob("*.yaml")})
    assert {"bullet_dlo/_assets/robots/kuka_iiwa.yaml", "bullet_dlo/_assets/robots/panda.yaml",
            "bullet_dlo/_assets/urdf/ft_gripper.urdf", "bullet_dlo/_assets/scenes/lv_study.yaml",
            "bullet_dlo/_assets/specs/dr_small.yaml"} <= assets <= names
    dist_info = f"bullet_dlo-{VERSION}.dist-info"
    assert {n.split("/")[0] for n in names} == {"bullet_dlo", dist_info}  # nothing else at the top level
    entry_points = zipfile.ZipFile(wheel).read(f"{dist_info}/entry_points.txt").decode()
    assert "bullet-dlo = bullet_dlo.cli:main" in entry_points


def test_installed_copy_and_its_assets_are_used_from_another_directory(venv, tmp_path):
    probe = """
import json, importlib.metadata, bullet_dlo
from bullet_dlo.assets import ROBOTS_DIR, URDF_DIR
from bullet_dlo.config.robot import robot_names
from bullet_dlo.robots.compose import robot_urdf
from bullet_dlo.config.robot import load_robot_spec
dist = importlib.metadata.distribution("bullet_dlo")
print(json.dumps({"file": bullet_dlo.__file__, "robots": str(ROBOTS_DIR), "urdf": str(URDF_DIR),
                  "names": robot_names(), "version": dist.version, "dist": str(dist.locate_file("")),
                  "kuka_urdf": str(robot_urdf(load_robot_spec("kuka")))}))
"""
    (tmp_path / "tmp").mkdir()
    out = run([venv / "bin" / "python", "-c", probe], cwd=tmp_path, env=clean_env(TMPDIR=str(tmp_path / "tmp")))
    found = json.loads(out.splitlines()[-1])
    package = Path(found["file"]).parent
    assert package.is_relative_to(venv), f"imported {found['file']}, not the copy installed in {venv}"
    assert not package.is_relative_to(ROOT)
    assert Path(found["robots"]) == package / "_assets" / "robots"
    assert Path(found["urdf"]) == package / "_assets" / "urdf"
    assert found["names"] == sorted(ROBOTS)
    assert (found["version"], Path(found["dist"])) == (VERSION, package.parent)
    assert Path(found["kuka_urdf"]).parent == tmp_path / "tmp" / f"bullet_dlo_urdf_{os.getuid()}"
    composed = Path(found["kuka_urdf"]).read_text()
    assert "ft_sensor_joint" in composed and "lbr_iiwa_link_7" in composed


def test_examples_copy_from_the_installed_wheel_and_the_documented_paths_then_exist(venv, tmp_path):
    """A pip user has no demos/ folder: ``bullet-dlo examples DIR`` puts the README's scene and spec paths there."""
    run([venv / "bin" / "bullet-dlo", "examples", "ex"], cwd=tmp_path, env=clean_env())
    for rel in ("demos/scenes/lv_study.yaml", "demos/specs/dr_small.yaml"):
        assert (tmp_path / "ex" / rel).read_bytes() == (ROOT / rel).read_bytes()


@pytest.mark.parametrize("robot", ROBOTS)
def test_grasp_runs_from_the_installed_wheel(venv, tmp_path, robot):
    script = venv / "bin" / "bullet-dlo"
    assert script.read_text().splitlines()[0] == f"#!{venv / 'bin' / 'python'}"
    duration, dt = 0.5, 1.0 / 240.0
    cwd, tmp = tmp_path / "cwd", tmp_path / "tmp"
    cwd.mkdir(), tmp.mkdir()
    run([script, "grasp", "--robot", robot, "--duration", duration, "--json", "grasp.json"], cwd=cwd,
        env=clean_env(NUMBA_DISABLE_JIT="1", TMPDIR=str(tmp)), timeout=120)
    # the numbers and their picture (cli.outputs), nothing else left in the working directory
    assert sorted(os.listdir(cwd)) == ["grasp.json", "grasp.png"]
    result = json.loads((cwd / "grasp.json").read_text())
    assert result["robot"] == robot and result["stable"]
    assert result["steps"] == round(duration / dt)
    # the wrists carry the cable: the sensors' vertical forces balance its weight, and agree with the model
    assert abs(result["force_balance_error"]) < 0.05
    assert result["sensor_vs_model_error"] < 0.10


def joints_in_file(urdf: Path) -> set[str]:
    """Names of the joints the URDF file declares."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        robot = yourdfpy.URDF.load(str(urdf), build_scene_graph=False, load_meshes=False).robot
    return {joint.name for joint in robot.joints}


def joints_as_loaded(urdf: Path, client: int) -> set[str] | None:
    """Names of the joints PyBullet builds from the URDF file (None if it rejects the file)."""
    try:
        body = pb.loadURDF(str(urdf), useFixedBase=True, flags=pb.URDF_USE_INERTIA_FROM_FILE, physicsClientId=client)
    except pb.error:
        return None
    names = {pb.getJointInfo(body, j, physicsClientId=client)[1].decode()
             for j in range(pb.getNumJoints(body, physicsClientId=client))}
    pb.removeBody(body, physicsClientId=client)
    return names


def test_robots_load_on_install_paths_of_any_length(tmp_path, monkeypatch):
    """Compose and load both robots with pybullet_data and urdf/ under 24 consecutive path lengths.

    The composed KUKA + gripper embeds the absolute mesh paths of pybullet_data; written as one
    ~10 kB line, PyBullet's parser rejected it, or dropped joints, for some of these lengths.
    """
    data = Path(pybullet_data.getDataPath())
    specs = [load_robot_spec(name) for name in ROBOTS]
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path / "tmp"))  # composed files go here, not to /tmp
    (tmp_path / "tmp").mkdir()
    client = pb.connect(pb.DIRECT)
    failed, lengths = [], []
    try:
        for pad in range(1, 25):
            prefix = tmp_path / ("p" * pad) / "site-packages"
            for spec in specs:
                link_tree(data / Path(spec.urdf).parts[0], prefix / "pybullet_data" / Path(spec.urdf).parts[0])
            link_tree(compose.URDF_DIR, prefix / "bullet_dlo" / "urdf")
            monkeypatch.setattr(pybullet_data, "getDataPath", lambda p=prefix: str(p / "pybullet_data"))
            monkeypatch.setattr(compose, "URDF_DIR", prefix / "bullet_dlo" / "urdf")
            lengths.append(len(str(prefix.resolve())))
            for spec in specs:
                path = compose.robot_urdf(spec)
                # written (fingers rigid, gripper composed): meshes referred to by absolute paths under the prefix
                assert path.is_relative_to(tmp_path / "tmp") and str(prefix.resolve()) in path.read_text()
                expected = joints_in_file(path)
                assert spec.sensor_joint in expected
                if joints_as_loaded(path, client) != expected:  # rejected, or loaded with joints missing
                    failed.append((spec.name, lengths[-1]))
    finally:
        pb.disconnect(client)
    assert failed == [], f"(robot, prefix length) that did not load, of lengths {lengths}: {failed}"


def test_old_module_paths_import_as_aliases_of_the_new_modules(tmp_path):
    """Every 0.1 module path imports (fresh interpreter, so each warns once) and is the new module itself."""
    script = tmp_path / "old_script.py"
    script.write_text(f"""
import importlib, json, sys, warnings
warnings.simplefilter("always")
from bullet_dlo._aliases import OLD_TO_NEW
report = {{}}
for short in {OLD_PATHS + NOW_SUBPACKAGES!r}:
    old = "bullet_dlo." + short
    with warnings.catch_warnings(record=True) as caught:
        module = importlib.import_module(old)
    new = OLD_TO_NEW.get(old, old)
    real = sys.modules[new]
    report[old] = {{"new": new, "same": module is real, "name": real.__name__, "spec": real.__spec__.name,
                   "origin": real.__spec__.origin, "file": getattr(real, "__file__", None),
                   "warnings": [(str(w.message), w.category.__name__, w.filename, w.lineno) for w in caught
                                if " moved to " in str(w.message)]}}
print(json.dumps(report))
""")
    report = json.loads(run([sys.executable, script], cwd=tmp_path).splitlines()[-1])
    (import_line,) = [i for i, line in enumerate(script.read_text().splitlines(), 1) if "import_module(old)" in line]
    assert set(report) == {f"bullet_dlo.{m}" for m in OLD_PATHS + NOW_SUBPACKAGES}
    for old, r in report.items():
        assert r["same"], old
        assert r["name"] == r["spec"] == r["new"], f"importing {old} renamed {r['new']}"
        assert r["origin"] == r["file"], old
        if old.removeprefix("bullet_dlo.") in NOW_SUBPACKAGES:
            assert r["new"] == old and r["warnings"] == [], old
        else:
            assert r["new"] != old
            assert [w[:2] for w in r["warnings"]] == [
                [f"{old} moved to {r['new']}; the old path goes in the next release", "DeprecationWarning"]]
            assert r["warnings"][0][2:] == [str(script), import_line]  # points at the line that imported it


def test_readme_names_import_from_old_paths_and_old_modules_are_attributes():
    import bullet_dlo

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        from bullet_dlo.bullet_scene import BulletWorld
        from bullet_dlo.dataset import Dataset
        from bullet_dlo.dual_arm import DualArmConfig, DualArmScene
        from bullet_dlo.stability import critical_dt

        assert bullet_dlo.stability.critical_dt is critical_dt is bullet_dlo.critical_dt
        assert bullet_dlo.resolve is sys.modules["bullet_dlo.analysis.resolve"]
    assert BulletWorld.__module__.startswith("bullet_dlo.bullet.")
    assert Dataset.__module__.startswith("bullet_dlo.data")
    assert DualArmScene.__module__.startswith("bullet_dlo.robots.dual_arm")
    assert DualArmConfig(robot="panda", dt=1e-3).robot == "panda"  # as the README builds it
    with pytest.raises(AttributeError):
        bullet_dlo.no_such_module


def test_simulate_is_the_function_and_its_module_path_says_so():
    import bullet_dlo
    from bullet_dlo.core.engine import simulate

    assert bullet_dlo.simulate is simulate
    with pytest.raises(ModuleNotFoundError, match="bullet_dlo.simulate is the function"):
        __import__("bullet_dlo.simulate")
