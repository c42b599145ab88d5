"""``bullet-dlo examples DIR``: the shipped example scenes and capture specs are copied, load, and are never
overwritten (the wheel's side: tests/test_packaging.py)."""
from __future__ import annotations

from pathlib import Path

from bullet_dlo.cli.examples import copy_examples
from bullet_dlo.cli.main import main
from bullet_dlo.config.capture import CaptureSpec
from bullet_dlo.config.scene import Scene

ROOT = Path(__file__).resolve().parents[2]


def test_every_example_is_copied_and_loads(tmp_path):
    copied, kept = copy_examples(tmp_path)
    names = {p.relative_to(tmp_path).as_posix() for p in copied}
    expect = {p.relative_to(ROOT).as_posix() for k in ("scenes", "specs") for p in (ROOT / "demos" / k).glob("*.yaml")}
    assert names == expect and not kept and "demos/scenes/lv_study.yaml" in names
    for path in copied:
        loaded = (Scene if "scenes" in path.parts else CaptureSpec).from_yaml(path)
        assert loaded is not None


def test_a_second_copy_keeps_what_is_there(tmp_path, capsys):
    mine = tmp_path / "demos" / "scenes" / "lv_study.yaml"
    mine.parent.mkdir(parents=True)
    mine.write_text("# my own edits\n")
    assert main(["examples", str(tmp_path)]) == 0
    assert mine.read_text() == "# my own edits\n" and "kept" in capsys.readouterr().out
    assert (tmp_path / "demos" / "specs" / "dr_small.yaml").is_file()


def test_a_target_under_a_file_is_one_line_exit_2(tmp_path, capsys):
    (tmp_path / "f").write_text("")
    assert main(["examples", str(tmp_path / "f" / "sub")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: DIR")
