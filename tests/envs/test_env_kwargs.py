"""Every keyword argument of every registered environment, and ``reset``'s seed and options, go through
one validation layer (:mod:`bullet_dlo.envs.params`): a generated corpus of bad values, each refused
with a ParameterError of one line naming the keyword, through ``gymnasium.make`` and direct
construction, before anything is built (no Bullet world: each refusal costs milliseconds); valid
values, boundaries included, still construct; the corpus covers every keyword of every constructor
(read from the signatures, so a new keyword without bad values fails here)."""
from __future__ import annotations

import importlib
import inspect
import math
import time

import gymnasium as gym
import numpy as np
import pytest

import bullet_dlo  # noqa: F401  (registers the ids)
from bullet_dlo._gym_registration import ENV_IDS
from bullet_dlo.core.validate import ParameterError
from bullet_dlo.envs import params

pytestmark = pytest.mark.bullet

NAN, INF = math.nan, math.inf
TINY_DT = {"sample": {"dt": {"dist": "fixed", "value": 1e-5}}}  # [s] the smallest physics step a spec allows
SLOT_N = {"dist": "fixed", "value": 16}  # Routing-v0 with the capture spec's cable (0.3 m, 4 mm): its slot floor


def env_class(env_id: str) -> type:
    module, name = ENV_IDS[env_id][0].split(":")
    return getattr(importlib.import_module(module), name)


def constructor_kwargs(cls: type) -> set[str]:
    """Every keyword the constructors of ``cls`` and its bases (up to gym.Env) take."""
    out = set()
    for klass in cls.__mro__:
        if klass is gym.Env or "__init__" not in vars(klass):
            continue
        for p in inspect.signature(klass.__init__).parameters.values():
            if p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY) and p.name != "self":
                out.add(p.name)
    return out


def number_bad_values(name: str) -> list:
    """Bad values of a numeric kwarg of :data:`params.NUMBERS`: below, at an excluded low end, above, huge,
    non-finite, wrong types (strings, None, bools, lists, complex)."""
    lo, hi, _, lo_open = params.NUMBERS[name]
    bad = [lo - 1.0, lo - 1e-9, hi * 1.01 + 1e-9, 1e12, -1e12, NAN, INF, -INF, "abc", "0.1", None, True, False,
           [0.1], (0.1, 0.2), {"value": 0.1}, 1j, np.array([0.1, 0.2])]
    if lo_open:
        bad += [lo, np.float64(lo)]
    return bad


SIZE_BAD = [(64,), (10**6, 10**6), (4097, 64), (64, 4097), (0, 64), (-64, 64), (15, 64), (64.5, 64), (NAN, 64),
            (INF, 64), ("64", "64"), "64", "ab", 64, None, True, (64, 64, 3), ((64, 64), (64, 64)),
            {"w": 64, "h": 64}, (True, 64), np.zeros((2, 2))]
FLAG_BAD = ["false", "False", "true", "", 0, 1, 0.0, None, NAN, [True], "yes"]
SHAPE_POINTS_BAD = [1, 0, -3, 2.5, 1001, 10**6, NAN, INF, "abc", "10", None, True, [10]]
CAMERA_BAD = ["RGB", "abc", "", 1, True, ["rgb"], ("rgb",), "human"]
# ("human" and "rgb_array_list" are not here: gymnasium.make serves them with its own wrappers over "rgb_array")
RENDER_MODE_BAD = ["rgb", "RGB_ARRAY", "depth", "", 1, True, ["rgb_array"]]
RANDOMISATION_BAD = [5, 1.5, True, [1, 2], b"spec.yaml", {"foo": 1}, {"sample": 3},
                     {"sample": {"dt": {"dist": "fixed", "value": -1}}}, {"sample": {"robot": "nobot"}},
                     "/nonexistent/spec.yaml", "/tmp"]
TENSION_RANGE_BAD = [(4.0, 1.0), (-1.0, 4.0), (1.0, 1e12), (1.0, 101.0), (NAN, 4.0), (1.0, INF), 5.0, (1.0,),
                     (1.0, 2.0, 3.0), "ab", None, ("a", "b"), (None, 4.0), {"low": 1, "high": 4}, (True, 4.0)]

SPECIAL = {"image_size": SIZE_BAD, "render_size": SIZE_BAD, "privileged": FLAG_BAD, "shape_points": SHAPE_POINTS_BAD,
           "camera": CAMERA_BAD, "render_mode": RENDER_MODE_BAD, "randomisation": RANDOMISATION_BAD,
           "tension_range": TENSION_RANGE_BAD}

# rows beyond one kwarg's own range: the step caps (a tiny physics step) and the control-rate rule
CROSS = [({"randomisation": TINY_DT, "settle_time": 10.0}, "settle_time", "at most 100000"),
         ({"randomisation": TINY_DT, "control_dt": 0.5}, "control_dt", "at most 10000"),
         ({"randomisation": TINY_DT, "control_dt": 1.0, "settle_time": 0.0}, "control_dt", "at most 10000"),
         ({"control_dt": 0.051}, "control_dt", "whole multiple")]


def corpus() -> list[tuple[str, dict, str, str]]:
    """(env id, kwargs, kwarg named, expected word) for every kwarg of every registered environment."""
    rows = []
    for env_id in ENV_IDS:
        for name in sorted(constructor_kwargs(env_class(env_id))):
            if name in SPECIAL:
                bad, word = SPECIAL[name], name
            else:
                bad, word = number_bad_values(name), params.range_text(name)
            rows += [(env_id, {name: value}, name, word) for value in bad]
        rows += [(env_id, kwargs, name, word) for kwargs, name, word in CROSS]
    return rows


CORPUS = corpus()


def through_make(row) -> bool:
    """Whether ``gymnasium.make`` lets the env see this row: make reads ``render_mode`` itself before calling the
    constructor (``render_mode.endswith``: an AttributeError inside Gymnasium for a non-string), so those values are
    checked by direct construction only."""
    _, kwargs, name, _ = row
    return not (name == "render_mode" and not isinstance(kwargs.get("render_mode"), str))


MAKE_CORPUS = [row for row in CORPUS if through_make(row)]
RESET_BAD = [({"options": {"foo": 1}}, "options"), ({"options": {"reset_mask": np.ones(1, bool)}}, "options"),
             ({"options": "abc"}, "options"), ({"options": [1]}, "options"), ({"options": 0}, "options"),
             ({"seed": -1}, "seed"), ({"seed": "abc"}, "seed"), ({"seed": 1.5}, "seed"), ({"seed": NAN}, "seed"),
             ({"seed": True}, "seed"), ({"seed": [1]}, "seed")]


def clear_error(make, name: str, word: str) -> str | None:
    """None if ``make()`` raises a clear ParameterError (one line naming ``name`` and ``word``), else what went wrong."""
    try:
        make()
    except ParameterError as err:
        msg = str(err)
        if "\n" in msg or name not in msg or word not in msg:
            return f"unclear message {msg!r}"
        return None
    except Exception as err:  # noqa: BLE001 - the corpus measures exactly this
        return f"{type(err).__name__}: {err}"
    return "accepted"


def row_id(row) -> str:
    env_id, kwargs, _, _ = row
    return f"{env_id.split('/')[1]}-" + ",".join(f"{k}={params.short(v, 30)}" for k, v in kwargs.items())


def test_the_corpus_covers_every_kwarg_of_every_environment():
    for env_id in ENV_IDS:
        kwargs = constructor_kwargs(env_class(env_id))
        covered = {name for e, _, name, _ in CORPUS if e == env_id}
        assert kwargs == covered, (env_id, kwargs ^ covered)
        assert all(sum(1 for e, _, n, _ in CORPUS if e == env_id and n == k) >= 5 for k in kwargs)
    assert len(CORPUS) > 500


@pytest.mark.parametrize("row", MAKE_CORPUS, ids=row_id)
def test_a_bad_kwarg_is_refused_by_make_with_one_line_naming_it(row):
    env_id, kwargs, name, word = row
    assert clear_error(lambda: gym.make(env_id, **kwargs), name, word) is None


def test_every_bad_value_gives_a_clear_error_through_make_and_direct_construction():
    """The share of clear errors over the corpus (both construction paths) and bad reset inputs: 100 %, each fast."""
    failures, total, start, slowest = [], 0, time.perf_counter(), 0.0
    for row in CORPUS:
        env_id, kwargs, name, word = row
        cls = env_class(env_id)
        makers = [lambda c=cls, k=kwargs: c(**k)]
        if through_make(row):
            makers.append(lambda e=env_id, k=kwargs: gym.make(e, **k))
        for make in makers:
            t0 = time.perf_counter()
            problem = clear_error(make, name, word)
            slowest = max(slowest, time.perf_counter() - t0)
            total += 1
            if problem:
                failures.append((env_id, kwargs, problem))
    for env_id in ENV_IDS:
        env = gym.make(env_id)
        for kwargs, name in RESET_BAD:
            total += 1
            problem = clear_error(lambda e=env, k=kwargs: e.reset(**k), name, name)
            if problem:
                failures.append((env_id, kwargs, problem))
        assert env.unwrapped.physics is None  # refused before building a world
        env.close()
    share = 1.0 - len(failures) / total
    print(f"\nclear errors: {total - len(failures)}/{total} = {100 * share:.1f} % "
          f"({time.perf_counter() - start:.2f} s, slowest {1e3 * slowest:.0f} ms; {len(CORPUS)} corpus rows, "
          f"{len(CORPUS) - len(MAKE_CORPUS)} of them by direct construction only)")
    assert not failures, failures[:10]
    assert share == 1.0  # (no simulation behind a refusal: asserted by physics None above, not by a clock)


VALID = [
    ("bullet_dlo/TensionTracking-v0", {"control_dt": 1.0, "settle_time": 0.0, "max_speed": 2.0, "workspace": 2.0,
                                       "privileged": np.bool_(True), "shape_points": np.int64(5), "camera": "rgbd",
                                       "image_size": np.array([16, 4096]), "render_size": [4096, 16],
                                       "render_mode": "rgb_array", "tension_range": [0, 100], "max_amplitude": 0,
                                       "target_offset": 0.5, "overload": 1000}),
    ("bullet_dlo/TensionTracking-v0", {"control_dt": np.float32(0.1), "settle_time": 10, "max_speed": 1e-6,
                                       "workspace": 1e-6, "shape_points": 1000.0, "tension_range": (2.0, 2.0),
                                       "max_amplitude": 1.0, "overload": 1e-3, "randomisation": None}),
    ("bullet_dlo/Shaping-v0", {"privileged": False, "inward": 0, "lateral": 0.5, "vertical": 0.0,
                               "success_error": 0.5, "shape_points": 2, "camera": "depth"}),
    ("bullet_dlo/Routing-v0", {"max_yaw_rate": 10, "force_soft": 1000.0, "overload": 0.5, "camera": "rgb",
                               "max_speed": 0.1, "workspace": 0.1,
                               "randomisation": {"sample": {"robot": "panda", "n_masses": SLOT_N}}}),
    ("bullet_dlo/Routing-v0", {"randomisation": {"sample": {**TINY_DT["sample"], "n_masses": SLOT_N}},
                               "control_dt": 0.1, "settle_time": 1.0}),  # both caps exactly
]


@pytest.mark.parametrize("env_id, kwargs", VALID, ids=[f"{e.split('/')[1]}-{i}" for i, (e, _) in enumerate(VALID)])
def test_valid_values_construct_as_given(env_id, kwargs):
    env = gym.make(env_id, **kwargs)
    u = env.unwrapped
    for name, value in kwargs.items():
        if name == "randomisation":
            continue
        got = getattr(u, name)
        want = tuple(value) if name in ("image_size", "render_size", "tension_range") else value
        assert got == pytest.approx(want) if not isinstance(want, (str, type(None))) else got == want, name
        assert type(got) in (float, int, bool, str, tuple, type(None)), (name, type(got))
    if "shape_points" in kwargs and u.privileged:
        assert u.observation_space["cable"].shape == (int(kwargs["shape_points"]), 3)
    env.close()


def test_defaults_are_unchanged():
    u = gym.make("bullet_dlo/TensionTracking-v0").unwrapped
    assert (u.control_dt, u.max_speed, u.workspace, u.settle_time, u.privileged, u.shape_points, u.camera,
            u.image_size, u.render_mode, u.render_size) == (0.05, 0.05, 0.1, 0.25, False, 10, None, (64, 64), None,
                                                          (320, 240))
    assert (u.tension_range, u.max_amplitude, u.target_offset, u.overload) == ((1.0, 4.0), 0.5, 0.04, 30.0)
    s = gym.make("bullet_dlo/Shaping-v0").unwrapped
    assert (s.privileged, s.inward, s.lateral, s.vertical, s.success_error, s.task_dim) == (True, 0.06, 0.05, 0.04,
                                                                                           0.005, 30)
    r = gym.make("bullet_dlo/Routing-v0").unwrapped
    assert (r.max_speed, r.max_yaw_rate, r.force_soft, r.overload) == (0.1, 1.0, 5.0, 30.0)


def test_valid_reset_inputs_still_reset():
    """None or {} options (a vector env's reset_mask leaves {}) and NumPy integer seeds; the same seed, the same scene."""
    env = gym.make("bullet_dlo/Routing-v0", settle_time=0.0)
    try:
        obs_a, _ = env.reset(seed=np.int64(3), options={})
        obs_b, _ = env.reset(seed=3, options=None)
        np.testing.assert_array_equal(obs_a["task"], obs_b["task"])
        env.reset()
    finally:
        env.close()
