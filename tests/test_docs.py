"""Every code block of the README and the docs site runs, and the site builds with warnings as errors.

Conventions (docs/development.md, "The docs are tested"):

* ```python blocks run; the blocks of one page share one namespace and run in page order, in a
  temporary directory in which ``demos/`` is the repository's;
* ```bash / ```console blocks: every ``bullet-dlo`` line is parsed by the real argument parser
  (the subcommand's ``--help`` exits 0, every option it names exists), every ``python demos/X.py``
  line names an existing script and options it defines; a block preceded by ``<!-- run -->`` is
  also run for real, in the page's directory, in page order with the page's python blocks;
* ```yaml blocks are parsed; those with a ``cable:`` section are scene files (``Scene.from_dict``);
* ``<!-- no-run: reason -->`` right before a block skips it; every skip must give its reason.
"""
from __future__ import annotations

import contextlib
import io
import os
import re
import shlex
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest
import yaml

ROOT = Path(__file__).resolve().parents[1]
PAGES = sorted((ROOT / "docs").rglob("*.md")) + [ROOT / "README.md"]
FENCE = re.compile(r"^```(\S*)\s*$")
MARK = re.compile(r"^<!--\s*(run|no-run)\s*(?::\s*(.*?))?\s*-->\s*$")
SHELL = ("bash", "console", "sh", "shell")


@dataclass
class Block:
    page: Path
    line: int  # 1-based line of the opening fence
    lang: str
    code: str
    mark: str | None  # None, "run" or "no-run"
    reason: str | None

    def __str__(self) -> str:
        return f"{self.page.relative_to(ROOT)}:{self.line} ({self.lang})"


def blocks(page: Path) -> list[Block]:
    """The fenced code blocks of ``page`` with the marker comment right before each (if any)."""
    lines = page.read_text().split("\n")
    out, k = [], 0
    while k < len(lines):
        m = FENCE.match(lines[k])
        if not m:
            k += 1
            continue
        start = k
        end = next(j for j in range(k + 1, len(lines)) if lines[j].strip() == "```")
        prev = next((lines[j] for j in range(start - 1, -1, -1) if lines[j].strip()), "")
        mark = MARK.match(prev.strip())
        out.append(Block(page, start + 1, m.group(1).lower(), "\n".join(lines[start + 1:end]),
                         mark.group(1) if mark else None, (mark.group(2) or "").strip() if mark else None))
        k = end + 1
    return out


ALL = [b for p in PAGES for b in blocks(p)]


def page_id(page: Path) -> str:
    return str(page.relative_to(ROOT))


def commands(block: Block) -> list[list[str]]:
    """The commands of a shell block: comments dropped, ``&&`` chains split, each as argv."""
    out = []
    for line in block.code.split("\n"):
        line = line.strip()
        if line.startswith("$ "):
            line = line[2:]
        if not line or line.startswith("#"):
            continue
        for part in line.split("&&"):
            argv = shlex.split(part, comments=True)
            if argv:
                out.append(argv)
    return out


def parse_cli(argv: list[str]) -> int:
    """Exit code of the real parser on ``argv`` (0: parsed), its error text swallowed."""
    from bullet_dlo.cli.main import build_parser

    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        try:
            build_parser().parse_args(argv)
        except SystemExit as exc:
            return 0 if exc.code in (0, None) else (exc.code if isinstance(exc.code, int) else 2)
    return 0


def subcommand(argv: list[str]) -> list[str]:
    """The subcommand words of a ``bullet-dlo`` argv (global -q dropped): ``bench stability``, ``dataset summary``."""
    words = [a for a in argv if a not in ("-q", "--quiet")]
    nested = {"bench", "dataset", "validate"}
    return words[:2] if words and words[0] in nested and len(words) > 1 else words[:1]


# ----- the site builds --------------------------------------------------------------------------

def test_site_builds_strict(tmp_path):
    """``mkdocs build --strict``: broken links, unrenderable docstrings and missing pages fail."""
    env = dict(os.environ, NO_MKDOCS_2_WARNING="1")
    proc = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "-q", "-f", str(ROOT / "mkdocs.yml"),
                           "-d", str(tmp_path / "site")], cwd=ROOT, capture_output=True, text=True, env=env,
                          timeout=300)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    assert (tmp_path / "site" / "reference" / "sim" / "index.html").exists()
    assert (tmp_path / "site" / "gallery" / "side_by_side_frame.png").exists()


# ----- markers ----------------------------------------------------------------------------------

def test_every_skip_has_a_reason():
    skipped = [b for b in ALL if b.mark == "no-run"]
    missing = [str(b) for b in skipped if not b.reason]
    assert not missing, f"no-run without a reason: {missing}"
    for page in PAGES:  # a marker must sit right before a block
        lines = page.read_text().split("\n")
        for k, line in enumerate(lines):
            if MARK.match(line.strip()):
                nxt = next((x for x in lines[k + 1:] if x.strip()), "")
                assert FENCE.match(nxt), f"{page_id(page)}:{k + 1}: marker not followed by a code block"
    runnable = [b for b in ALL if b.lang in ("python",) + SHELL + ("yaml",)]
    print(f"\n{len(ALL)} code blocks, {len(runnable)} checked, {len(skipped)} marked no-run:")
    for b in skipped:
        print(f"  {b}: {b.reason}")
    assert len(skipped) <= 12, "more than a dozen skipped blocks: the docs should run"


def test_readme_keeps_the_setup_commands():
    text = (ROOT / "README.md").read_text()
    assert "pip install -e . && python demos/main_demo.py" in text
    assert 'pip install -e ".[test]" && python -m pytest -q -n 2' in text
    ci = (ROOT / ".ci" / "run").read_text()
    assert 'pip install -e ".[test]" && python -m pytest -q -n 2' in ci  # exactly the README's command
    assert "from bullet_dlo.sim import Scene, build" in text


# ----- shell blocks -----------------------------------------------------------------------------

SHELL_BLOCKS = [b for b in ALL if b.lang in SHELL and b.mark != "no-run"]


@pytest.mark.parametrize("block", SHELL_BLOCKS, ids=str)
def test_shell_block_parses(block):
    """Every command of the block is known: ``bullet-dlo`` lines parse, demo scripts exist with their options."""
    cmds = commands(block)
    assert cmds, f"{block}: empty shell block"
    for argv in cmds:
        if argv[0] == "bullet-dlo":
            sub = subcommand(argv[1:])
            assert parse_cli(sub + ["--help"]) == 0, f"{block}: bullet-dlo {' '.join(sub)} --help fails"
            assert parse_cli(argv[1:]) == 0, f"{block}: the parser refuses {shlex.join(argv)}"
        elif argv[0] == "python" and len(argv) > 1 and argv[1].startswith("demos/"):
            script = ROOT / argv[1]
            assert script.is_file(), f"{block}: no {argv[1]}"
            source = script.read_text()
            for opt in (a.split("=")[0] for a in argv[2:] if a.startswith("--")):
                assert f'"{opt}"' in source or f"'{opt}'" in source, f"{block}: {argv[1]} has no {opt}"
        else:
            pytest.fail(f"{block}: {shlex.join(argv)} cannot be checked: mark the block <!-- no-run: reason -->")


# ----- yaml blocks ------------------------------------------------------------------------------

@pytest.mark.parametrize("block", [b for b in ALL if b.lang == "yaml" and b.mark != "no-run"], ids=str)
def test_yaml_block_is_a_valid_scene(block):
    from bullet_dlo.config.scene import Scene

    data = yaml.safe_load(block.code)
    assert isinstance(data, dict), f"{block}: not a mapping"
    if "cable" in data:
        Scene.from_dict(data)


# ----- python blocks and the blocks run for real, page by page ----------------------------------

RUN_PAGES = sorted({b.page for b in ALL if b.mark != "no-run" and (b.lang == "python" or (b.lang in SHELL
                                                                                          and b.mark == "run"))})


@pytest.mark.parametrize("page", RUN_PAGES, ids=page_id)
def test_page_runs(page, tmp_path, monkeypatch):
    """The page's python blocks (one namespace) and its ``<!-- run -->`` shell blocks, in page order."""
    (tmp_path / "demos").symlink_to(ROOT / "demos")
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("MPLBACKEND", "Agg")
    namespace: dict = {"__name__": "__docs__"}
    for block in blocks(page):
        if block.mark == "no-run":
            continue
        if block.lang == "python":
            try:
                exec(compile(block.code, str(block), "exec"), namespace)
            except Exception as exc:  # noqa: BLE001 (the block's own error, with where it is)
                pytest.fail(f"{block} raised {type(exc).__name__}: {exc}")
        elif block.lang in SHELL and block.mark == "run":
            for argv in commands(block):
                assert argv[0] == "bullet-dlo", f"{block}: only bullet-dlo commands run for real"
                proc = subprocess.run([sys.executable, "-c", "import sys; from bullet_dlo.cli import main; "
                                       "sys.exit(main(sys.argv[1:]))", *argv[1:]], cwd=tmp_path,
                                      capture_output=True, text=True, timeout=120)
                assert proc.returncode == 0, f"{block}: {shlex.join(argv)} exited {proc.returncode}\n" + \
                    proc.stdout[-2000:] + proc.stderr[-2000:]
