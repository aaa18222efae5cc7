"""Fault injection: environment configurations, actions, reset options, evaluation scenarios
and the filter's noise scaling; and a soak of the batched environment under hostile actions.

Every bad value is refused when it is given (a one-line ConfigError or ValueError naming the
field or the argument and what it allows), never later as a NaN reward or a traceback; every
accepted configuration and action keeps observations, rewards and infos finite.
"""

from __future__ import annotations

import math
import time
from unittest import mock

import gymnasium as gym
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

import aeromag_env  # noqa: F401  (registers the environment)
from aeromag_env.cli.main import main
from aeromag_env.compensation.kalman import FilterState
from aeromag_env.configs import from_dict
from aeromag_env.environment import vec_env
from aeromag_env.environment.config import EnvConfig, env_config
from aeromag_env.environment.env import parameters
from aeromag_env.environment.legacy import LEGACY_KEYS, LEGACY_SWITCHES
from aeromag_env.environment.prefetch import FlightKey, simulate
from aeromag_env.environment.scenarios import make_episode
from aeromag_env.environment.spaces import check_actions
from aeromag_env.environment.vec_env import AeroMagCompensationVecEnv
from aeromag_env.errors import AeromagError, ConfigError
from agents.evaluation.episodes import evaluate
from tests._helpers import assert_one_line_error, examples, observations

NAN, INF = math.nan, math.inf
#: (field, bad value, what the message must say besides the field's name).
CONFIG_FAULTS: list[tuple[str, object, str]] = [
    ("scenario", "windy", "valid scenarios"),
    ("scenario", 5, "valid scenarios"),
    ("scenario", None, "valid scenarios"),
    ("decision_window", 0, "integer in"),
    ("decision_window", -1, "integer in"),
    ("decision_window", 2.5, "integer"),
    ("decision_window", True, "integer"),
    ("decision_window", "10", "integer"),
    ("decision_window", 10**7, "integer in"),
    ("action", {"s_max": NAN}, r"action\.s_max .*> 1"),
    ("action", {"s_max": INF}, "> 1"),
    ("action", {"s_max": 1.0}, "> 1"),
    ("action", {"s_max": -2.0}, "> 1"),
    ("action", {"s_max": "2"}, "number"),
    ("action", {"s_max": 2 + 0j}, "number"),
    ("reward", {"scale_nt": 0.0}, r"reward\.scale_nt .*\[nT\]"),
    ("reward", {"scale_nt": -1.0}, r"\[nT\]"),
    ("reward", {"scale_nt": NAN}, r"\[nT\]"),
    ("reward", {"scale_nt": INF}, r"\[nT\]"),
    ("reward", {"scale_nt": 1e-300}, r"\[nT\]"),
    ("reward", {"form": None}, "string"),
    ("reward", {"divergence_penalty": NAN}, r"reward\.divergence_penalty .*\[-1e\+06, 0\]"),
    ("reward", {"divergence_penalty": INF}, r"\[-1e\+06, 0\]"),
    ("reward", {"divergence_penalty": -INF}, r"\[-1e\+06, 0\]"),
    ("reward", {"divergence_penalty": 5.0}, r"\[-1e\+06, 0\]"),
    ("reward", {"divergence_penalty": -1e300}, r"\[-1e\+06, 0\]"),
    ("score_from", NAN, r"\[0, 1\)"),
    ("score_from", -0.1, r"\[0, 1\)"),
    ("score_from", 1.0, r"\[0, 1\)"),
    ("score_from", "0.5", "number"),
    ("action", {"scale_limit": INF}, r"action\.scale_limit .*\(1, 1e\+100\]"),
    ("action", {"scale_limit": NAN}, r"\(1, 1e\+100\]"),
    ("action", {"scale_limit": 1.0}, r"\(1, 1e\+100\]"),
    ("action", {"scale_limit": -1.0}, r"\(1, 1e\+100\]"),
    ("action", {"scale_limit": 1e300}, r"\(1, 1e\+100\]"),
    ("duration_s", 0.0, r"\[s\]"),
    ("duration_s", -1.0, r"\[s\]"),
    ("duration_s", NAN, r"\[s\]"),
    ("duration_s", INF, r"\[s\]"),
    ("duration_s", 0.05, r"\[s\]"),
    ("duration_s", 1e9, r"\[s\]"),
    ("duration_s", "60", "number"),
    ("action", {"q_log10": (NAN, 1.0)}, r"action\.q_log10 .*decades"),
    ("action", {"q_log10": (-INF, INF)}, "decades"),
    ("action", {"q_log10": (1.0,)}, "lo < hi"),
    ("action", {"q_log10": (0.0, 1.0, 2.0)}, "lo < hi"),
    ("action", {"q_log10": (0.0, 400.0)}, "decades"),
    ("action", {"q_log10": (-101.0, 0.0)}, "decades"),
    ("action", {"q_log10": ("a", "b")}, "numbers"),
    ("action", {"q_log10": 5}, "list"),
    ("action", {"r_log10": (-1e308, 1e308)}, r"action\.r_log10 .*decades"),
    ("action", {"qp_log10": (2.0, 2.0)}, r"action\.qp_log10 .*lo < hi"),
    ("observations", ("log_ror", "log_qoq", "windspeed"), "valid observations"),
    ("observations", ("log_qoq", "log_ror"), "starting with log_ror, log_qoq"),
    ("observations", ("log_ror", "log_qoq", "progress", "progress"), "each once"),
    ("observations", ("log_ror", "log_qoq", "log_qp_scale"), "needs a T_p action"),
    ("observations", "log_ror", "list"),
    ("action", {"mode": "both"}, "relative or absolute"),
    ("action", {"permanent": "gate"}, "needs action.mode='absolute'"),
    ("action", {"permanent": "half"}, "joint, graded, gate"),
    ("action", {"q_log10": (1.0, 0.0)}, "lo < hi"),
    ("action", 2.0, "an ActionSpec"),
    ("reward", {"form": "cubic"}, "one of log, linear, squared"),
    ("reward", {"scale_nt": 0.0}, r"\[nT\]"),
    ("preset", "fancy", "valid presets: paper, nonstationary, general"),
]
IDS = [f"{f}={v!r}" for f, v, _ in CONFIG_FAULTS]


@pytest.mark.parametrize(("field", "value", "allowed"), CONFIG_FAULTS, ids=IDS)
def test_bad_config_values_are_refused_naming_the_field(field, value, allowed):
    with pytest.raises(ConfigError) as direct:
        if field in EnvConfig.__dataclass_fields__ and not isinstance(value, dict):
            EnvConfig(**{field: value})
        else:  # a preset or a partial spec
            env_config(**{field: value})
    assert_one_line_error(direct.value, patterns=(f"(?i){field}", allowed))
    with pytest.raises(ConfigError) as made:  # as gym.make and a JSON config give it
        gym.make("AeroMagCompensation-v0", config={field: value})
    assert_one_line_error(made.value, patterns=(f"(?i){field}",))
    with pytest.raises(ConfigError):
        AeroMagCompensationVecEnv(2, **{field: value})


def test_nan_divergence_penalty_no_longer_reaches_the_rewards():
    """The issue's case: ``divergence_penalty=NaN`` gave NaN rewards on divergence."""
    with pytest.raises(ConfigError, match="divergence_penalty"):
        gym.make("AeroMagCompensation-v0", reward={"divergence_penalty": NAN})


@pytest.mark.parametrize("key", sorted([*LEGACY_KEYS, *LEGACY_SWITCHES]))
def test_the_first_versions_flat_keys_are_refused_by_the_environment(key):
    """The environment speaks presets and specs; a flat key of its first version is refused,
    naming it and where old files are read (:mod:`aeromag_env.environment.legacy`)."""
    for make in (
        lambda: env_config(**{key: True}),
        lambda: gym.make("AeroMagCompensation-v0", config={key: True}),
        lambda: AeroMagCompensationVecEnv(2, **{key: True}),
    ):
        with pytest.raises(ConfigError) as info:
            make()
        assert_one_line_error(info, f"unknown field '{key}'", "legacy.upgrade")


@pytest.mark.parametrize(
    "field,value",
    [
        ("decision_window", 1),
        ("decision_window", 10**6),
        ("action", {"s_max": 1.0000001}),
        ("action", {"s_max": 1e308}),
        ("reward", {"scale_nt": 1e-3}),
        ("reward", {"scale_nt": 1e6}),
        ("reward", {"divergence_penalty": 0.0}),
        ("reward", {"divergence_penalty": -1e6}),
        ("score_from", 0.0),
        ("score_from", 0.999),
        ("action", {"scale_limit": 1.0000001}),
        ("action", {"scale_limit": 1e100}),
        ("duration_s", 1.0),
        ("duration_s", 86_400.0),
        ("action", {"q_log10": (-100.0, 100.0)}),
        ("action", {"r_log10": [-1, 3]}),
    ],
)
def test_values_at_the_bounds_are_accepted(field, value):
    cfg = from_dict(EnvConfig, {field: value})
    assert np.all(np.isfinite(parameters(cfg)))


ACTION_FAULTS = [
    ("complex", np.array([0.5 + 1j, 0.0])),
    ("complex_list", [1j, 0.0]),
    ("complex_real_only", np.array([0.5 + 0j, 0.0])),
    ("object", np.array([0.5, 0.5], dtype=object)),
    ("strings", ["0.5", "0.5"]),
    ("bytes", np.array([b"1", b"0"])),
    ("bool", np.array([True, False])),
    ("none", None),
    ("dict", {"a_q": 0.5}),
    ("ragged", [[0.5], [0.5, 0.5]]),
    ("nan", [NAN, 0.0]),
    ("inf", [INF, 0.0]),
    ("minus_inf", [0.0, -INF]),
    ("too_long", [0.0, 0.0, 0.0]),
    ("scalar", 0.5),
    ("datetime", np.array(["2020-01-01", "2020-01-02"], dtype="datetime64[D]")),
]


@pytest.mark.parametrize(("case", "action"), ACTION_FAULTS, ids=[c for c, _ in ACTION_FAULTS])
def test_bad_actions_are_refused(case, action):
    with pytest.raises(ValueError) as single:
        check_actions(action, size=2)
    assert_one_line_error(single.value)
    with pytest.raises(ValueError) as vec:
        check_actions([action, action], num_envs=2, size=2)
    assert_one_line_error(vec.value)


def test_complex_actions_never_reach_the_environments():
    env = gym.make("AeroMagCompensation-v0", duration_s=30.0)
    env.reset(seed=100_000)
    with pytest.raises(ValueError, match="complex"):
        env.step(np.array([0.5 + 1j, 0.0]))
    venv = AeroMagCompensationVecEnv(2, duration_s=30.0)
    venv.reset(seed=0)
    with pytest.raises(ValueError, match="complex"):
        venv.step(np.array([[0.5 + 1j, 0.0], [0.0, 0.0]]))


@pytest.mark.parametrize(
    "action",
    [
        [1e308, -1e308],
        [-1e308, 1e308],
        [1.0, -1.0],
        [3.4e38, 0.0],
        [1, 0],
        np.array([65504.0, -65504.0], np.float16),
        np.array([-1.0, 1.0], np.float32),
    ],
)
def test_huge_finite_actions_are_clipped(action):
    a = check_actions(action, size=2)
    assert a.dtype == np.float64 and np.all(np.isfinite(a))
    env = gym.make("AeroMagCompensation-v0", duration_s=30.0)
    env.reset(seed=100_000)
    obs, reward, _, _, info = env.step(action)
    assert np.all(np.isfinite(obs)) and math.isfinite(reward)
    assert all(math.isfinite(v) for v in info.values())


@pytest.mark.parametrize("options", [[("scenario", "paper")], ("scenario",), "scenario", 5, True])
def test_reset_options_must_be_a_dict(options):
    env = gym.make("AeroMagCompensation-v0", duration_s=30.0)
    with pytest.raises(ConfigError, match="options must be a dict") as info:
        env.reset(seed=1, options=options)
    assert_one_line_error(info.value)
    venv = AeroMagCompensationVecEnv(2, duration_s=30.0)
    with pytest.raises(ConfigError, match="options must be a dict"):
        venv.reset(seed=1, options=options)


def test_unknown_reset_options_are_refused():
    env = gym.make("AeroMagCompensation-v0", duration_s=30.0)
    with pytest.raises(ConfigError, match=r"unknown reset option.*scenarioo.*valid: scenario"):
        env.reset(seed=1, options={"scenarioo": "paper"})
    with pytest.raises(ConfigError, match="scenario"):
        env.reset(seed=1, options={"scenario": ["paper"]})
    venv = AeroMagCompensationVecEnv(2, duration_s=30.0)
    with pytest.raises(ConfigError, match=r"unknown reset option.*mask.*reset_mask, scenario"):
        venv.reset(seed=1, options={"mask": np.ones(2, bool)})
    env.reset(seed=1, options={})  # empty and None stay fine
    env.reset(seed=1, options=None)
    assert env.reset(seed=1, options={"scenario": "paper"})[1]["flight_seed"] >= 0


def test_evaluate_refuses_a_training_only_scenario(tmp_path, capsys):
    with pytest.raises(AeromagError, match=r"nonstationary_dense.*training only") as info:
        evaluate("nonstationary_dense", ["constant"], [100_000])
    assert_one_line_error(info.value)
    args = [
        "evaluate",
        "--scenario",
        "nonstationary_dense",
        "--policies",
        "constant",
        "--episodes",
        "1",
        "--out",
        str(tmp_path / "out"),
        "--quiet",
    ]
    assert main(args) == 2
    err = capsys.readouterr().err.strip()
    assert "training only" in err and err.count("\n") == 0
    assert not (tmp_path / "out").exists()


@pytest.fixture(scope="module")
def short_filter() -> FilterState:
    ep = make_episode("paper", 0, duration_s=20.0)
    return FilterState(ep.filter_cfg, ep.y, ep.t_b, ep.tdot_b, store_states=False)


@pytest.mark.parametrize("bad", [NAN, INF, -INF, 0.0, -1.0, -0.0, "2", None, 2 + 0j, True])
def test_scale_noise_refuses_non_positive_and_non_finite(short_filter, bad):
    qd, rm = short_filter.qd.copy(), short_filter.rm.copy()
    for args in ((bad, 1.0), (1.0, bad)):
        with pytest.raises(
            ConfigError, match=r"scale_noise: s_[qr] must be a finite number > 0"
        ) as e:
            short_filter.scale_noise(*args)
        assert_one_line_error(e.value)
    np.testing.assert_array_equal(short_filter.qd, qd)  # refused before anything changed
    np.testing.assert_array_equal(short_filter.rm, rm)


def test_scale_noise_still_scales(short_filter):
    qd, rm = short_filter.qd.copy(), short_filter.rm.copy()
    short_filter.scale_noise(4.0, 0.25)
    np.testing.assert_array_equal(short_filter.qd, qd * 4.0)
    np.testing.assert_array_equal(short_filter.rm, rm * 0.25)
    short_filter.scale_noise(np.float32(0.25), 4)
    np.testing.assert_array_equal(short_filter.qd, qd)


# --- property-based: any value for any field, any array as an action ---------------------------

HOSTILE = (
    st.floats(allow_nan=True, allow_infinity=True)
    | st.integers(-(10**20), 10**20)
    | st.booleans()
    | st.none()
    | st.text(max_size=6)
    | st.complex_numbers(allow_nan=True)
    | st.lists(st.floats(allow_nan=True, allow_infinity=True), max_size=3)
    | st.tuples(st.floats(-1e3, 1e3), st.floats(-1e3, 1e3))
)
FIELDS = sorted([*EnvConfig.__dataclass_fields__, "preset"])


@settings(max_examples=examples(400), deadline=None)
@given(field=st.sampled_from(FIELDS), value=HOSTILE)
def test_any_value_for_any_config_field(field, value):
    """Either the value is refused with a one-line ConfigError naming the field (directly and
    through the JSON path), or the configuration is usable: its compiled parameters finite."""
    for make in (
        lambda: env_config(**{field: value}),
        lambda: from_dict(EnvConfig, {field: value}),
    ):
        try:
            cfg = make()
        except ConfigError as e:
            assert_one_line_error(e, field)
            continue
        assert np.all(np.isfinite(parameters(cfg)))
        assert cfg.duration_s is None or 1.0 <= cfg.duration_s <= 86_400.0


ACTION_ARRAYS = hnp.arrays(
    dtype=st.sampled_from(
        [np.float16, np.float32, np.float64, np.int8, np.int64, np.uint8, np.complex128, np.bool_]
    ),
    shape=hnp.array_shapes(min_dims=0, max_dims=2, max_side=3),
)


@pytest.fixture(scope="module")
def stepping_env() -> gym.Env:
    env = gym.make(
        "AeroMagCompensation-v0",
        duration_s=600.0,
        observations=observations("log_qp_scale"),
        action={"permanent": "graded"},
    )
    env.reset(seed=100_000)
    return env


@settings(max_examples=examples(300), deadline=None)
@given(action=ACTION_ARRAYS | st.lists(st.floats(), min_size=3, max_size=3))
def test_any_action_is_refused_or_keeps_everything_finite(stepping_env, action):
    try:
        a = check_actions(action, size=3)
    except ValueError as e:
        assert_one_line_error(e)
        return
    assert a.shape == (3,) and a.dtype == np.float64 and np.all(np.isfinite(a))
    obs, reward, terminated, truncated, info = stepping_env.step(action)
    assert np.all(np.isfinite(obs)) and math.isfinite(reward)
    assert all(math.isfinite(v) for v in info.values())
    if terminated or truncated:
        stepping_env.reset()


@pytest.mark.slow
def test_window_statistics_after_a_huge_r_swing():
    """The environment's configuration allows R over ±100 decades (absolute mode): the window's
    running sums of tr S then lost the small terms to the subtraction of a huge one (ROR NaN
    from a negative sum, or ~1e-80 from a residual) until the next lap's re-sum; they are now
    summed afresh when the term leaving carried nearly all of a sum. Found by the soak (seeded:
    env 3, step 9; NaN from step 9 before)."""
    config = {
        "scenario": "calibration_then_survey",
        "action": {"mode": "absolute", "r_log10": (-100.0, 100.0), "scale_limit": 1e100},
    }
    rng = np.random.default_rng(20)
    with mock.patch.object(vec_env, "simulate", _FlightPool()):
        env = AeroMagCompensationVecEnv(32, **config)
        env.reset(seed=24)
        for t in range(12):
            _, _, _, _, infos = env.step(_actions("random", t, (32, 2), rng))
            assert np.all(np.isfinite(infos["ror"])), f"step {t}"


@pytest.mark.parametrize("seed", range(3))
def test_the_window_sums_hold_terms_100_decades_apart(seed):
    """``window_add``'s running sums against math.fsum of the window's last M terms, for tr S
    and |r|² that jump between 1e-50 and 1e+50 (the environment's R over ±100 decades): within
    1e-12 relative at every sample (they were negative, or 1e80× too large, before)."""
    from aeromag_env.compensation.kernel_layout import ACC, INTS, N_ACC, N_INT
    from aeromag_env.compensation.window import window_add

    m, rng = 50, np.random.default_rng(seed)
    rbuf, sbuf, acc, ints = np.zeros((m, 3)), np.zeros(m), np.zeros(N_ACC), np.zeros(N_INT, int)
    ints[INTS.window] = m
    level = 10.0 ** rng.choice([-50.0, 0.0, 50.0], size=600).repeat(3)  # runs of 3 samples
    r_all = rng.standard_normal((level.size, 3)) * np.sqrt(level)[:, None]
    s_all = level * rng.uniform(1.0, 2.0, level.size)
    for k in range(level.size):
        window_add(r_all[k], s_all[k], rbuf, sbuf, acc, ints)
        lo = max(0, k + 1 - m)
        want_s = math.fsum(s_all[lo : k + 1])
        want_rr = math.fsum((r_all[lo : k + 1] ** 2).sum(axis=1))
        want_xy = math.fsum(r_all[lo : k + 1, 0] * r_all[lo : k + 1, 1])
        assert acc[ACC.s] == pytest.approx(want_s, rel=1e-12), k
        assert acc[ACC.rr] == pytest.approx(want_rr, rel=1e-12), k
        assert acc[ACC.c + 1] == pytest.approx(want_xy, rel=1e-9, abs=1e-12 * want_rr), k


# --- soak: the batched environment under random, extreme and adversarial actions ---------------

SOAK_CONFIGS = [
    {"scenario": "nominal"},
    {
        "scenario": "nonstationary",
        "observations": observations(
            "log_qp_scale",
            "log_innovation_power",
            "log_mean_innovation_power",
            "log_step_statistic",
        ),
        "action": {
            "mode": "absolute",
            "permanent": "gate",
            "scale_limit": 1e10,
            "q_log10": (-4.0, 4.0),
            "r_log10": (-1.0, 3.0),
            "qp_log10": (-2.0, 10.0),
        },
    },
    {
        "scenario": "misspecified",
        "observations": observations("log_qp_scale"),
        "action": {"permanent": "graded", "s_max": 1e3, "scale_limit": 1e100},
    },
    {
        "scenario": "paper",
        "decision_window": 1,
        "reward": {"form": "squared", "scale_nt": 1e-3, "divergence_penalty": -1e6},
        "duration_s": 300.0,
    },
    # R within the default ±3 decades: see test_window_statistics_after_a_huge_r_swing
    {
        "scenario": "calibration_then_survey",
        "observations": observations(),
        "action": {"mode": "absolute", "q_log10": (-100.0, 100.0), "scale_limit": 1e100},
        "reward": {"form": "linear"},
    },
    {
        "scenario": "nonstationary_dense",
        "decision_window": 50,
        "observations": observations(
            "log_qp_scale", "log_innovation_power", "log_mean_innovation_power"
        ),
        "action": {"permanent": "graded"},
        "score_from": 0.0,
        "duration_s": 600.0,
    },
]
EXTREMES = np.array([1e308, -1e308, 1.0, -1.0, 0.0, 3.4e38, -3.4e38, 1.0000001, -1.0000001])


def _actions(kind: str, t: int, shape: tuple[int, int], rng: np.random.Generator) -> np.ndarray:
    """Action sequences: random in and beyond [-1, 1], extremes, bang-bang at ±1e308 and at
    ±1, alternating per environment, constant max Q and min R, and sign flips of huge values."""
    n, m = shape
    if kind == "random":
        return rng.uniform(-1.5, 1.5, shape)
    if kind == "extreme":
        return rng.choice(EXTREMES, shape)
    if kind == "bang_bang":
        return np.full(shape, 1e308 if t % 2 else -1e308)
    if kind == "bang_bang_bounds":
        return np.full(shape, 1.0 if (t // 3) % 2 else -1.0)
    if kind == "alternating":
        return np.where((np.arange(n)[:, None] + np.arange(m) + t) % 2 == 0, 1.0, -1.0)
    if kind in ("max_q_min_r", "min_q_max_r"):
        a = np.full(shape, 1e308 if kind == "max_q_min_r" else -1e308)
        a[:, 1] = -a[:, 1]
        return a
    return rng.choice([-1.0, 1.0], shape) * 10.0 ** rng.uniform(0, 308, shape)  # "flips"


KINDS = (
    "random",
    "extreme",
    "bang_bang",
    "bang_bang_bounds",
    "alternating",
    "max_q_min_r",
    "min_q_max_r",
    "flips",
)


def _assert_finite(obs: np.ndarray, rewards: np.ndarray, infos: dict, where: str) -> None:
    assert np.all(np.isfinite(obs)), f"{where}: non-finite observation"
    assert np.all(np.isfinite(rewards)), f"{where}: non-finite reward"
    for key, values in infos.items():
        if key.startswith("_"):
            continue
        have = infos[f"_{key}"]
        assert np.all(np.isfinite(np.asarray(values, dtype=float)[have])), f"{where}: info {key}"


class _FlightPool:
    """``simulate`` over a pool of :data:`POOL` flights per scenario and duration: hostile
    actions make the filter diverge and the episode end on almost every step, and simulating
    a new flight for each (10 ms) would take the soak's time; the soak tests the step, not
    the simulator (which has its own tests)."""

    POOL = 4

    def __init__(self) -> None:
        self.flights: dict[tuple, object] = {}

    def __call__(self, key: FlightKey) -> object:
        pooled = key._replace(flight_seed=key.flight_seed % self.POOL)
        if pooled not in self.flights:
            self.flights[pooled] = simulate(pooled)
        return self.flights[pooled]


def soak(total_steps: int, num_envs: int = 32, seed: int = 20) -> dict[str, float]:
    """Step every configuration of :data:`SOAK_CONFIGS` with every action kind until
    ``total_steps`` environment steps are done; returns the counts and the time."""
    rng = np.random.default_rng(seed)
    per = total_steps // (len(SOAK_CONFIGS) * len(KINDS) * num_envs) + 1
    steps, episodes, t0 = 0, 0, time.perf_counter()
    with mock.patch.object(vec_env, "simulate", _FlightPool()):
        for c, config in enumerate(SOAK_CONFIGS):
            env = AeroMagCompensationVecEnv(num_envs, **config)
            obs, infos = env.reset(seed=seed + c)
            shape = (num_envs, env.single_action_space.shape[0])
            for kind in KINDS:
                for t in range(per):
                    obs, rewards, ended, cut, infos = env.step(_actions(kind, t, shape, rng))
                    _assert_finite(obs, rewards, infos, f"config {c} {kind} step {t}")
                    episodes += int(np.count_nonzero(ended | cut))
                steps += per * num_envs
            env.close()
    return {"steps": steps, "episodes": episodes, "seconds": time.perf_counter() - t0}


@pytest.mark.slow
def test_soak_200k_steps_stay_finite():
    result = soak(200_000)
    assert result["steps"] >= 200_000 and result["episodes"] > 0


@pytest.mark.slow
def test_soak_1m_steps_stay_finite():
    result = soak(1_000_000)
    print(f"soak: {result}")
    assert result["steps"] >= 1_000_000
