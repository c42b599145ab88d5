"""Bad recordings for ``bullet-dlo fit`` (issue 26, item 3): every format the loader reads (CSV, NPZ,
HDF5) x every damage a tester found, each refused with one ParameterError line naming the problem
(the CLI: exit code 2, one stderr line), before any simulation; valid files in each format still load.
Only loading and validation run here (no fit)."""
from __future__ import annotations

import json
import os
import pickle
import re

import h5py
import numpy as np
import pytest

from bullet_dlo.cli.main import main
from bullet_dlo.core.validate import ParameterError
from bullet_dlo.data.recording import MAX_DURATION, MAX_SAMPLES, read_recording

FORMATS = (".csv", ".npz", ".h5")
FIELDS = ("x", "y", "z", "qx", "qy", "qz", "qw", "fx", "fy", "fz")
K = 50  # samples at 100 Hz
CABLE = ["--length", "0.3", "--diameter", "0.004"]


def base(k: int = K, rate: float = 100.0, tension: float = 2.0) -> dict[str, np.ndarray]:
    """A plausible SI recording: grippers 0.3 m apart facing each other, a cable of 30 g in tension."""
    t = np.arange(k) / rate
    pos = np.empty((k, 2, 3))
    pos[:, 0] = (-0.15, 0.0, 0.35)
    pos[:, 1] = (0.15, 0.0, 0.35)
    pos[:, :, 2] += 0.01 * np.sin(t)[:, None]
    quat = np.zeros((k, 2, 4))
    quat[:, 0, 0] = 1.0  # half turn about x
    quat[:, 1, 1] = 1.0  # half turn about y
    force = np.zeros((k, 2, 3))
    force[:, 0] = (tension, 0.0, -0.147)
    force[:, 1] = (-tension, 0.0, -0.147)
    return {"t": t, "ee_pos": pos, "ee_quat": quat, "force": force}


def write(path, cols, units=None, header=None, dtype=None):
    """``cols`` (base()'s keys) in the format of ``path``'s suffix; units: column -> unit stated in the file."""
    units = units or {}
    if path.suffix == ".csv":
        names = header or ["t"] + [f"{arm}_{c}" for arm in ("left", "right") for c in FIELDS]
        blocks = [np.asarray(cols["t"])[:, None]]
        for arm in (0, 1):
            blocks += [cols["ee_pos"][:, arm], cols["ee_quat"][:, arm], cols["force"][:, arm]]
        data = np.hstack(blocks)
        lines = [",".join(map(str, row)) for row in data.tolist()]
        if header is not False:
            lines.insert(0, ",".join(names))
        path.write_text("\n".join(lines) + "\n")
        return path
    arrays = {"t": cols["t"], "ee_pos": cols["ee_pos"], "ee_quat": cols["ee_quat"],
              "wrench_world": np.concatenate([cols["force"], np.zeros(cols["force"].shape)], axis=2)}
    if path.suffix == ".npz":
        np.savez(path, **arrays, attrs=np.array(json.dumps({"units": units})))
    else:
        with h5py.File(path, "w") as f:
            for key, arr in arrays.items():
                f.create_dataset(key, data=arr)
                if key in units:
                    f[key].attrs["units"] = units[key]
    return path


def csv_units(scale: dict[str, str]) -> list[str]:
    """A CSV header stating units: ``scale`` quantity -> unit (time, length, force)."""
    q = {"x": "length", "y": "length", "z": "length", "fx": "force", "fy": "force", "fz": "force"}
    names = [f"t [{scale.get('time', 's')}]"]
    for arm in ("left", "right"):
        names += [f"{arm}_{c} [{scale.get(q[c], 'm' if q[c] == 'length' else 'N')}]" if c in q else f"{arm}_{c}"
                  for c in FIELDS]
    return names


def damaged(data: bytes, how: str) -> bytes:
    if how == "empty":
        return b""
    if how == "truncated":
        return data[: len(data) // 2]
    flipped = bytearray(data)
    lo, hi = (0, 64) if data[:4] == b"\x89HDF" else (len(data) // 3, len(data) // 3 + 64)
    for i in range(lo, min(hi, len(data))):
        flipped[i] ^= 0xFF
    return bytes(flipped)


def scaled(**factors) -> dict[str, np.ndarray]:
    cols = base()
    return {k: v * factors.get(k, 1.0) for k, v in cols.items()}


def with_(key, fn):
    cols = base()
    cols[key] = fn(cols[key].copy())
    return cols


def _zero_quat(q):
    q[10, 1] = 0.0
    return q


def _back(t):
    t[20] = t[18]
    return t


def _dup(t):
    t[20] = t[19]
    return t


def _nan(p):
    p[5, 0, 1] = np.nan
    return p


# name -> (maker(path) -> kwargs for read_recording, regex the message must contain); maker writes the file
def _plain(cols, **kw):
    return lambda path: (write(path, cols, **kw), {})[1]


def _bytes_damage(how):
    def make(path):
        write(path, base())
        path.write_bytes(damaged(path.read_bytes(), how))
        return {}
    return make


def _complex(path):
    cols = base()
    if path.suffix == ".csv":
        write(path, cols)
        lines = path.read_text().splitlines()
        lines[3] = ",".join([lines[3].split(",")[0]] + ["1+2j"] + lines[3].split(",")[2:])
        path.write_text("\n".join(lines) + "\n")
    else:
        cols["ee_pos"] = cols["ee_pos"] + 1e-3j
        write(path, cols)
    return {}


def _text(path):
    cols = base()
    if path.suffix == ".csv":
        write(path, cols)
        lines = path.read_text().splitlines()
        lines[4] = ",".join(lines[4].split(",")[:5] + ["abc"] + lines[4].split(",")[6:])
        path.write_text("\n".join(lines) + "\n")
    else:
        cols["t"] = np.array([f"{v}" for v in cols["t"]]).astype("S")
        write(path, cols)
    return {}


def _long(k, rate):
    def make(path):
        cols = base(k=k, rate=rate)
        if path.suffix == ".csv" and k > MAX_SAMPLES:  # cheap: the count is taken before any parsing
            header = ",".join(["t"] + [f"{a}_{c}" for a in ("left", "right") for c in FIELDS])
            path.write_bytes(header.encode() + b"\n" + b"0,0,0,0,0,0,0,1,0,0,0,0,0,0,0,0,0,1,0,0,0\n" * k)
            return {}
        write(path, cols)
        return {}
    return make


def _unknown_unit(path):
    if path.suffix == ".csv":
        write(path, base(), header=csv_units({"length": "inch"}))
    else:
        write(path, base(), units={"ee_pos": "inch"})
    return {}


CORPUS = {
    "positions in mm, unstated": (_plain(scaled(ee_pos=1e3)), r"grasp position .* above 100 m: positions must be in metres"),
    "forces in mN, unstated": (_plain(scaled(force=1e3)), r"force up to .* above 1000 N: forces must be in newtons"),
    "time in ms, unstated": (_plain(scaled(t=1e3)), r"median time step 10 outside 1e-05\.\.1 s: times must be in seconds"),
    "unknown unit stated": (_unknown_unit, r"unit 'inch' not understood for length"),
    "complex column": (_complex, r"real number"),
    "text column": (_text, r"(holds text|real number)"),
    "empty file": (_bytes_damage("empty"), r"is empty"),
    "truncated file": (_bytes_damage("truncated"), r"(cannot be read as|rows have|not a numeric CSV|needs at least)"),
    "byte-flipped file": (_bytes_damage("flipped"), r"(cannot be read as|not a numeric CSV|header)"),
    "zero quaternion": (_plain(with_("ee_quat", _zero_quat)), r"quaternion of the right arm at sample 10 has norm 0"),
    "non-unit quaternion": (_plain(with_("ee_quat", lambda q: 2 * q)), r"quaternion .* norm 2"),
    "time goes back": (_plain(with_("t", _back)), r"time goes back at sample 20 .* must strictly increase"),
    "duplicate time": (_plain(with_("t", _dup)), r"time repeats at sample 20"),
    "NaN position": (_plain(with_("ee_pos", _nan)), r"column ee_pos holds NaN"),
    "2-hour recording": (_long(7200, 1.0), rf"lasts 7199 s .* more than the {MAX_DURATION:g} s .*--time-window"),
    "too many samples": (_long(MAX_SAMPLES + 10, 5000.0), rf"more than the {MAX_SAMPLES} a fit takes: cut it"),
    "too few samples": (_plain(base(k=2)), r"(at least 3 samples|needs at least 3)"),
}

CSV_ONLY = {
    "unlabelled columns": (_plain(base(), header=False), r"must have 21 columns named in a header line"),
    "wrongly named columns": (_plain(base(), header=["t"] + [f"c{i}" for i in range(20)]),
                              r"lacks left_x, left_y"),
    "duplicate column names": (_plain(base(), header=["t"] * 21), r"named more than once"),
    "fewer columns in rows": (lambda p: (p.write_text(",".join(csv_units({})) + "\n" + "0,1,2\n" * 5), {})[1],
                              r"(not a numeric CSV|rows have)"),
}


def _npz_pickled_column(path):
    cols = base()
    np.savez(path, t=cols["t"], ee_pos=np.array([object()] * K, dtype=object), ee_quat=cols["ee_quat"],
             wrench_world=np.zeros((K, 2, 6)))
    return {}


def _npz_is_a_pickle(path):
    path.write_bytes(pickle.dumps(base()))
    return {}


def _npy_as_npz(path):
    with open(path, "wb") as fh:
        np.save(fh, base()["t"])
    return {}


def _h5_link(kind):
    def make(path):
        cols = base()
        write(path, cols)
        with h5py.File(path, "a") as f:
            del f["ee_pos"]
            if kind == "external":
                other = path.with_name("other.h5")
                with h5py.File(other, "w") as g:
                    g["ee_pos"] = cols["ee_pos"]
                f["ee_pos"] = h5py.ExternalLink(str(other), "/ee_pos")
            elif kind == "soft":
                f["ee_pos"] = h5py.SoftLink("/elsewhere/ee_pos")
            elif kind == "virtual":
                other = path.with_name("other.h5")
                with h5py.File(other, "w") as g:
                    g["ee_pos"] = cols["ee_pos"]
                layout = h5py.VirtualLayout(shape=cols["ee_pos"].shape, dtype=float)
                layout[...] = h5py.VirtualSource(str(other), "ee_pos", shape=cols["ee_pos"].shape)
                f.create_virtual_dataset("ee_pos", layout)
            else:  # raw data in an external file
                f.create_dataset("ee_pos", shape=cols["ee_pos"].shape, dtype=float,
                                 external=[(str(path.with_name("raw.bin")), 0, h5py.h5f.UNLIMITED)])
        return {}
    return make


FORMAT_ONLY = {
    ".npz": {
        "pickled column": (_npz_pickled_column, r"pickled Python objects; .* allow_pickle=False"),
        "file is a pickle": (_npz_is_a_pickle, r"pickled Python objects; .* allow_pickle=False"),
        "a .npy named .npz": (_npy_as_npz, r"single \.npy array, not an NPZ archive"),
    },
    ".h5": {
        "external link": (_h5_link("external"), r"column ee_pos is an external link .* links are not followed"),
        "soft link out of the file": (_h5_link("soft"), r"column ee_pos is a soft link; links are not followed"),
        "virtual dataset": (_h5_link("virtual"), r"keeps its data in another file"),
        "external raw storage": (_h5_link("raw"), r"keeps its data in another file"),
    },
}
COMMON = {
    "not a recording suffix (.npy)": (".npy", _npy_as_npz, r"series file must end in"),
    "a FIFO": (".csv", lambda p: (os.mkfifo(p), {})[1], r"not a regular file"),
    "a folder": (".h5", lambda p: (p.mkdir(), {})[1], r"not a regular file"),
    "missing file": (".npz", lambda p: {}, r"not found"),
    "missing column": (".npz", lambda p: (np.savez(p, t=base()["t"]), {})[1], r"lacks column\(s\) ee_pos"),
    "column of the wrong length": (".h5", lambda p: (write(p, base()), _h5_trim(p), {})[2],
                                   r"column ee_pos has shape \(49, 2, 3\), not one row per time"),
}


def _h5_trim(path):
    with h5py.File(path, "a") as f:
        pos = f["ee_pos"][:-1]
        del f["ee_pos"]
        f["ee_pos"] = pos


def cases():
    out = []
    for fmt in FORMATS:
        for name, (make, pattern) in CORPUS.items():
            out.append((fmt, name, make, pattern))
        for name, (make, pattern) in (CSV_ONLY.items() if fmt == ".csv" else FORMAT_ONLY[fmt].items()):
            out.append((fmt, name, make, pattern))
    for name, (fmt, make, pattern) in COMMON.items():
        out.append((fmt, name, make, pattern))
    return out


CASES = cases()


def outcome(tmp_path, fmt, name, make):
    """(clear, message): clear when read_recording raised a one-line ParameterError."""
    folder = tmp_path / name.replace(" ", "_").replace("/", "_")
    folder.mkdir()
    path = folder / f"rec{fmt}"
    kwargs = make(path)
    try:
        read_recording(path, **kwargs)
    except ParameterError as err:
        return "\n" not in str(err), str(err)
    except Exception as err:  # noqa: BLE001 - anything else is what this test rules out
        return False, f"{type(err).__name__}: {err}"
    return False, "accepted"


@pytest.mark.parametrize("fmt,name,make,pattern", CASES, ids=[f"{c[0]}-{c[1]}" for c in CASES])
def test_bad_recording_is_one_clear_line(tmp_path, fmt, name, make, pattern):
    clear, message = outcome(tmp_path, fmt, name, make)
    assert clear, message
    assert re.search(pattern, message), message


def test_share_of_clear_errors_is_100_percent(tmp_path):
    results = [outcome(tmp_path, fmt, f"{fmt}-{name}", make) for fmt, name, make, _ in CASES]
    clear = sum(ok for ok, _ in results)
    assert len(CASES) >= 60
    assert clear / len(CASES) == 1.0, [m for ok, m in results if not ok]


@pytest.mark.parametrize("fmt", FORMATS)
def test_valid_recordings_load_and_stated_units_convert(tmp_path, fmt):
    cols = base()
    rec = read_recording(write(tmp_path / f"si{fmt}", cols))
    assert np.allclose(rec.grasp_pos, cols["ee_pos"]) and np.allclose(rec.force, cols["force"])
    assert np.allclose(rec.t, cols["t"]) and np.allclose(rec.grasp_quat, cols["ee_quat"])
    milli = scaled(t=1e3, ee_pos=1e3, force=1e3)
    if fmt == ".csv":
        path = write(tmp_path / f"milli{fmt}", milli, header=csv_units({"time": "ms", "length": "mm", "force": "mN"}))
    else:
        path = write(tmp_path / f"milli{fmt}", milli, units={"t": "ms", "ee_pos": "mm", "wrench_world": "mN, mN m"})
    back = read_recording(path)
    assert np.allclose(back.grasp_pos, cols["ee_pos"]) and np.allclose(back.force, cols["force"])
    assert np.allclose(back.t, cols["t"])
    # the units of an unlabelled file given by the caller (the CLI's --units)
    flagged = read_recording(write(tmp_path / f"flag{fmt}", milli), units="time=ms,length=mm,force=mN")
    assert np.allclose(flagged.grasp_pos, cols["ee_pos"]) and np.allclose(flagged.t, cols["t"])
    with pytest.raises(ParameterError, match="says it is in 'mm', the units given say 'm'"):
        if fmt == ".csv":
            read_recording(path, units="length=m")
        else:
            read_recording(path, units={"length": "m"})


def test_csv_columns_are_taken_by_name(tmp_path):
    cols = base()
    names = ["t"] + [f"{arm}_{c}" for arm in ("left", "right") for c in FIELDS]
    order = np.random.default_rng(1).permutation(21)
    path = write(tmp_path / "ordered.csv", cols)
    table = np.loadtxt(path, delimiter=",", skiprows=1)
    shuffled = tmp_path / "shuffled.csv"
    np.savetxt(shuffled, table[:, order], delimiter=",", header=",".join(names[i] for i in order), comments="")
    rec = read_recording(shuffled)
    assert np.allclose(rec.grasp_pos, cols["ee_pos"]) and np.allclose(rec.force, cols["force"])
    assert np.allclose(rec.t, cols["t"])


def test_a_time_window_cuts_a_long_recording(tmp_path):
    path = write(tmp_path / "long.h5", base(k=7200, rate=1.0))
    with pytest.raises(ParameterError, match="lasts"):
        read_recording(path)
    rec = read_recording(path, window=(3000.0, 3100.0))
    assert len(rec.t) == 101 and rec.t[0] == 0.0 and rec.t[-1] == 100.0


def run_cli(capsys, argv):
    code = main(argv)
    err = capsys.readouterr().err
    return code, err.strip().splitlines()


@pytest.mark.parametrize("fmt", FORMATS)
def test_cli_refuses_with_exit_2_and_one_line(tmp_path, capsys, fmt):
    out = ["--out", str(tmp_path / "fit")]
    long = write(tmp_path / f"long{fmt}", base(k=7200, rate=1.0))
    code, lines = run_cli(capsys, ["fit", str(long), *CABLE, *out])
    assert code == 2 and len(lines) == 1 and "more than the 120 s" in lines[0], lines
    good = write(tmp_path / f"good{fmt}", base())
    code, lines = run_cli(capsys, ["fit", str(good), *CABLE, "--n-masses", "100000", *out])
    assert code == 2 and lines == ["error: --n-masses must be an integer in [3, 200], got 100000"], lines
    # plausible-looking mm positions (a small set-up) and mN forces (a light cable): caught against the cable
    small = base(tension=0.2)
    small["ee_pos"] = small["ee_pos"] * 1e3 / 20  # grippers 15 mm apart written in mm
    code, lines = run_cli(capsys, ["fit", str(write(tmp_path / f"mm{fmt}", small)), *CABLE, *out])
    assert code == 2 and len(lines) == 1 and "grasp points up to 15 m apart" in lines[0], lines
    light = base(tension=0.2)
    light["force"] = light["force"] * 1e3  # written in mN, below the 1 kN plausibility limit
    code, lines = run_cli(capsys, ["fit", str(write(tmp_path / f"mN{fmt}", light)), *CABLE, *out])
    assert code == 2 and len(lines) == 1 and "density" in lines[0] and "must be in newtons" in lines[0], lines
    code, lines = run_cli(capsys, ["fit", str(write(tmp_path / f"mN2{fmt}", light)), *CABLE, "--mass", "0.03", *out])
    assert code == 2 and len(lines) == 1 and "more than 30 times the cable's" in lines[0], lines
    code, lines = run_cli(capsys, ["fit", str(good), *CABLE, "--units", "length=inch", *out])
    assert code == 2 and lines == ["error: units: unit 'inch' not understood for length (use m, cm, mm)"], lines


@pytest.mark.parametrize("fmt", FORMATS)
def test_a_sensor_held_between_its_readings_is_compared_at_its_fresh_samples(tmp_path, fmt):
    """A wrist sensor read at 100 Hz in a 1 kHz file (``arms.sensor_rate``) holds each reading for ten samples.
    Compared as they were, the held samples are a lagged copy of the signal and the sample-to-sample noise
    level came out 100x too small: every fit of such a file said "model discrepancy dominates". Now the reader
    marks the fresh samples (``use``), and the noise level on them is the sensor's."""
    from bullet_dlo.analysis.fit_recording import noise_scale
    from bullet_dlo.data.recording import write_series

    rng = np.random.default_rng(3)
    a = base(k=1000, rate=1000.0)
    held = np.repeat(rng.normal(0.0, 0.01, (100, 2, 3)), 10, axis=0)  # 10 mN noise, one draw per reading
    a["force"] = a["force"] + held
    wrench = np.concatenate((a["force"], np.zeros_like(a["force"])), axis=2)
    path = write_series(tmp_path / f"held{fmt}", {"t": a["t"], "ee_pos": a["ee_pos"], "ee_quat": a["ee_quat"],
                                                  "wrench_world": wrench})
    rec = read_recording(path)
    assert rec.use is not None and rec.use.sum() == 100 and np.array_equal(np.flatnonzero(rec.use), np.arange(0, 1000, 10))
    y = rec.force.reshape(1000, 6)
    assert 0.007 < noise_scale(y[rec.use]) < 0.013 and noise_scale(y) < 0.002
    a_fresh = base(k=1000, rate=1000.0)
    a_fresh["force"] = a_fresh["force"] + rng.normal(0.0, 0.01, (1000, 2, 3))
    path = write_series(tmp_path / f"fresh{fmt}", {"t": a_fresh["t"], "ee_pos": a_fresh["ee_pos"],
                                                   "ee_quat": a_fresh["ee_quat"],
                                                   "wrench_world": np.concatenate((a_fresh["force"],
                                                                                   np.zeros((1000, 2, 3))), axis=2)})
    assert read_recording(path).use is None  # a sensor read every sample: all compared
    a_fresh["force"][:500] = a_fresh["force"][0]  # a noise-free rest for half the file: no sensor clock, all compared
    path = write_series(tmp_path / f"rest{fmt}", {"t": a_fresh["t"], "ee_pos": a_fresh["ee_pos"],
                                                  "ee_quat": a_fresh["ee_quat"],
                                                  "wrench_world": np.concatenate((a_fresh["force"],
                                                                                  np.zeros((1000, 2, 3))), axis=2)})
    assert read_recording(path).use is None


@pytest.mark.parametrize("fmt", FORMATS)
def test_the_fit_takes_the_recording_simulations_number_of_masses_unless_given(tmp_path, fmt):
    """A series from a 14-mass simulation, fitted with the documented command (no --n-masses), was fitted with
    10 masses: its parameters were those of another discretisation, stated with confident intervals that missed
    the truth (E 0.91x, +-0.7 %). The series states its cable; the fit's model now takes its n, in every format."""
    from bullet_dlo.cli.fit import DEFAULT_N_MASSES, model_masses
    from bullet_dlo.data.recording import write_series

    a = base()
    cols = {"t": a["t"], "ee_pos": a["ee_pos"], "ee_quat": a["ee_quat"],
            "wrench_world": np.concatenate((a["force"], np.zeros_like(a["force"])), axis=2)}
    sim = read_recording(write_series(tmp_path / f"sim{fmt}", cols, {"integrator": "bdf2", "dt": 0.01,
                                                                    "cable": {"n_masses": 14, "length": 0.3}}))
    assert sim.source["n_masses"] == 14 and model_masses([sim]) == 14
    real = read_recording(write_series(tmp_path / f"real{fmt}", cols))
    assert real.source is None and model_masses([real]) == DEFAULT_N_MASSES
    assert model_masses([sim, real]) == DEFAULT_N_MASSES  # (they do not agree on one)


@pytest.mark.parametrize("fmt", FORMATS)
def test_a_simulated_file_states_its_cables_length_and_diameter(tmp_path, capsys, fmt):
    """A dataset episode states its cable (``params``), a grasp --series file too (``cable``), yet `fit` asked for
    --length and --diameter ("the recording does not state its cable's length"). Both are now read from the
    file; a file that states one of them still needs the other, and a real file both."""
    from bullet_dlo.cli.fit import stated_diameter
    from bullet_dlo.data.recording import write_series

    a = base()
    cols = {"t": a["t"], "ee_pos": a["ee_pos"], "ee_quat": a["ee_quat"],
            "wrench_world": np.concatenate((a["force"], np.zeros_like(a["force"])), axis=2)}
    series = read_recording(write_series(tmp_path / f"series{fmt}", cols, {
        "integrator": "bdf2", "dt": 0.01, "cable": {"n_masses": 14, "length": 0.31, "diameter": 0.004}}))
    assert series.length == 0.31 and stated_diameter([series]) == 0.004
    half = read_recording(write_series(tmp_path / f"half{fmt}", cols, {
        "integrator": "bdf2", "dt": 0.01, "cable": {"length": 0.31}}))
    assert half.length == 0.31 and stated_diameter([half]) is None
    assert stated_diameter([series, half]) == 0.004  # (the one stated)
    out = ["--out", str(tmp_path / "fit")]
    code, lines = run_cli(capsys, ["fit", str(tmp_path / f"half{fmt}"), *out])
    assert code == 2 and lines == ["error: --diameter is required: the cable's diameter [m], > 0 (the recording "
                                   "does not state it)"], lines
    code, lines = run_cli(capsys, ["fit", str(write(tmp_path / f"real{fmt}", base())), *out])
    assert code == 2 and lines == ["error: --length is required: the recording does not state its cable's length "
                                   "[m]"], lines
    if fmt == ".h5":  # a dataset episode: the cable in its ``params`` (JSON), as bullet-dlo capture writes it
        path = write(tmp_path / "episode.h5", base())
        with h5py.File(path, "a") as f:
            f.attrs["params"] = json.dumps({"integrator": "bdf2", "dt": 0.001, "n_masses": 12, "length": 0.3,
                                            "diameter": 0.005, "mass": 0.035})
        episode = read_recording(path)
        assert episode.length == 0.3 and stated_diameter([episode]) == 0.005 and episode.source["n_masses"] == 12
