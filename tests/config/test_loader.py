"""The one YAML loader: every way a file can fail gives one line naming the file."""
from __future__ import annotations

import pytest

from bullet_dlo.config.capture import CaptureSpec
from bullet_dlo.config.loader import load_mapping, load_yaml
from bullet_dlo.config.scene import Scene
from bullet_dlo.core.validate import ParameterError

READERS = [(Scene.from_yaml, "scene file"), (CaptureSpec.from_yaml, "capture spec")]


def one_line_error(fn, *args) -> str:
    with pytest.raises(ParameterError) as info:
        fn(*args)
    text = str(info.value)
    assert "\n" not in text
    return text


def test_plain_yaml_is_parsed_with_yaml_types(tmp_path):
    path = tmp_path / "ok.yaml"
    path.write_text("a: 1.0e-3\nb: [1, 2]\nc: {d: true}\n")
    assert load_yaml(path) == {"a": 1e-3, "b": [1, 2], "c": {"d": True}}
    (tmp_path / "empty.yaml").write_text("")
    assert load_yaml(tmp_path / "empty.yaml") is None


@pytest.mark.parametrize("read,what", READERS)
def test_missing_file_and_directory(tmp_path, read, what):
    missing = tmp_path / "nope.yaml"
    assert one_line_error(read, missing) == f"{what} {str(missing)!r} does not exist"
    assert "is a directory" in one_line_error(read, tmp_path)


@pytest.mark.parametrize("read,what", READERS)
def test_non_utf8_bytes_name_the_byte(tmp_path, read, what):
    path = tmp_path / "latin1.yaml"
    path.write_bytes("name: caf\u00e9\n".encode("latin-1"))  # 0xe9 alone is not UTF-8
    assert one_line_error(read, path).endswith("is not UTF-8 text (byte 9 is 0xe9)")


@pytest.mark.parametrize("read,what", READERS)
def test_invalid_yaml_names_line_and_column(tmp_path, read, what):
    path = tmp_path / "bad.yaml"
    path.write_text("seed: 1\nepisode: {duration: 1.0\nsample: {}\n")  # the flow mapping is never closed
    err = one_line_error(read, path)
    assert err.startswith(f"{what} {str(path)!r} is not valid YAML (line 3, column ")


def test_python_tags_are_refused_and_never_run(tmp_path):
    marker = tmp_path / "ran"
    path = tmp_path / "evil.yaml"
    path.write_text(f"cable: !!python/object/apply:os.system ['touch {marker}']\n")
    err = one_line_error(Scene.from_yaml, path)
    assert "Python object tags (!!python/...) are not allowed" in err and "line 1, column 8" in err
    assert not marker.exists()


def test_unknown_local_tags_are_refused(tmp_path):
    path = tmp_path / "tag.yaml"
    path.write_text("seed: !seed 3\n")
    assert "only standard YAML tags are allowed" in one_line_error(CaptureSpec.from_yaml, path)


def test_a_fifo_is_refused_without_blocking(tmp_path):
    import os

    fifo = tmp_path / "scene.yaml"
    os.mkfifo(fifo)  # reading it would block until a writer comes
    with pytest.raises(ParameterError, match="not a regular file"):
        load_mapping(fifo, "scene file")


def test_an_alias_bomb_is_refused_before_anything_walks_it(tmp_path):
    """Seven levels of nine aliases: 600 bytes that expand to 9^7 = 4.8 million values."""
    lines = ['a0: &a0 ["x","x","x","x","x","x","x","x","x"]']
    lines += [f"a{k}: &a{k} [" + ",".join([f"*a{k - 1}"] * 9) + "]" for k in range(1, 7)]
    bomb = tmp_path / "bomb.yaml"
    bomb.write_text("\n".join(lines + ["cable: {length: *a6}"]))
    with pytest.raises(ParameterError, match="expands to more than"):
        load_mapping(bomb, "scene file")


def test_an_output_name_too_long_for_the_file_system_is_one_line():
    from bullet_dlo.config.schema import output_dir, output_file

    with pytest.raises(ParameterError, match="--json is too long"):
        output_file("--json", "x" * 300 + ".json")
    with pytest.raises(ParameterError, match="--out is too long"):
        output_dir("--out", "/tmp/" + "d/" * 2100)
