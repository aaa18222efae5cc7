import functools
import json
import math
import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env as gym_check_env
from stable_baselines3.common.env_checker import check_env as sb3_check_env

import aeromag_env  # noqa: F401  (registers the environment)
from aeromag_env.configs import to_dict
from aeromag_env.environment.config import EnvConfig, env_config
from aeromag_env.environment.observations import NAMES
from aeromag_env.environment.scenarios import REGIME_STD_NT, SCENARIOS, make_episode
from aeromag_env.environment.spaces import (
    action_names,
    observation_bounds,
    observation_index,
    observation_names,
    observation_positions,
)
from aeromag_env.errors import ConfigError
from aeromag_env.simulation.interference import INDUCED_START, STATE_SLICES
from tests._helpers import observations

#: Absolute actions with a T_p action (graded): the general policy's mapping.
GRADED = {"mode": "absolute", "permanent": "graded"}

TP = STATE_SLICES["permanent"]


def _make(**kw):
    return gym.make("AeroMagCompensation-v0", **kw)


@pytest.mark.parametrize(
    "settings",
    [
        {},
        {"observations": observations()},
        {"observations": observations("log_qp_scale"), "action": {"permanent": "graded"}},
        {"preset": "general"},
    ],
)
def test_gymnasium_and_sb3_checkers_pass_without_warnings(settings):
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # any warning fails the test
        gym_check_env(_make(**settings).unwrapped)
        sb3_check_env(_make(**settings).unwrapped)


def _rollout(env, seed, actions):
    out = [env.reset(seed=seed)]
    for a in actions:
        out.append(env.step(a))
    return out


def test_same_seed_same_actions_identical():
    rng = np.random.default_rng(0)
    actions = rng.uniform(-1, 1, (60, 2)).astype(np.float32)
    a = _rollout(_make(scenario="nonstationary"), 100_000, actions)
    b = _rollout(_make(scenario="nonstationary"), 100_000, actions)
    for x, y in zip(a, b, strict=True):
        assert json.dumps(x, default=lambda o: o.tolist()) == json.dumps(
            y, default=lambda o: o.tolist()
        )
    c = _rollout(_make(scenario="nonstationary"), 100_001, actions)
    assert c[-1][1] != a[-1][1]  # another seed, another flight


def test_config_round_trips_through_gym_make_as_a_dict():
    cfg = env_config(
        scenario="misspecified",
        decision_window=20,
        observations=observations(),
        action={"s_max": 3.0},
    )
    env = _make(config=json.loads(json.dumps(to_dict(cfg))))
    assert env.unwrapped.config == cfg
    assert env.observation_space.shape == (7,)
    assert _make(config=cfg, decision_window=5).unwrapped.config.decision_window == 5


def test_reward_is_the_documented_formula_and_episode_ends_truncated():
    env = _make(scenario="nominal")
    env.reset(seed=100_000)
    done, steps = False, 0
    while not done:
        _, reward, terminated, truncated, info = env.step(np.zeros(2, np.float32))
        assert reward == pytest.approx(-math.log1p(info["rmse_window_nt"] / 1.0))
        done, steps = terminated or truncated, steps + 1
    assert truncated and not terminated
    assert steps == math.ceil(env.unwrapped.episode.n / 10)
    assert 0 < info["episode_rmse_nt"] < 10 and info["divergences"] == 0


FORMULAS = {"linear": lambda e: -e / 4.0, "squared": lambda e: -((e / 4.0) ** 2)}


@pytest.mark.parametrize(("form", "formula"), FORMULAS.items())
def test_reward_forms_are_the_documented_formulas_over_the_same_windows(form, formula):
    runs = {}
    for f in ("log", form):
        env = _make(config={"scenario": "nominal", "reward": {"form": f, "scale_nt": 4.0}})
        env.reset(seed=100_001)
        runs[f] = [env.step(np.zeros(2, np.float32))[1::3] for _ in range(30)]
    for (r_log, info_log), (r, info) in zip(runs["log"], runs[form], strict=True):
        assert info["rmse_window_nt"] == info_log["rmse_window_nt"]  # the form changes no flight
        assert r_log == pytest.approx(-math.log1p(info["rmse_window_nt"] / 4.0))
        assert r == pytest.approx(formula(info["rmse_window_nt"]))
    with pytest.raises(ConfigError, match=r"reward\.form.*one of log, linear, squared"):
        _make(config={"reward": {"form": "cubic"}})


def test_actions_are_clipped_and_nan_rejected():
    env = _make()
    env.reset(seed=100_000)
    env.step(np.array([5.0, -5.0], np.float32))
    log_q, log_r = env.unwrapped.log_scales
    assert log_q == pytest.approx(math.log(2.0))  # clipped to +1 → ×2
    assert log_r == pytest.approx(-math.log(2.0))
    with pytest.raises(ValueError, match="finite"):
        env.step(np.array([np.nan, 0.0], np.float32))


def test_scale_limit_holds():
    env = _make(action={"scale_limit": 16.0})
    env.reset(seed=100_000)
    for _ in range(10):
        _, _, _, _, info = env.step(np.ones(2, np.float32))
    assert info["q_scale"] == pytest.approx(16.0) and info["r_scale"] == pytest.approx(16.0)


def test_divergence_terminates_with_the_penalty():
    env = _make()
    env.reset(seed=100_000)
    env.unwrapped.filter.qd[:] = 1e300  # a covariance that overflows on the next predict
    _, reward, terminated, truncated, info = env.step(np.zeros(2, np.float32))
    assert terminated and not truncated and reward == -10.0 and info["divergences"] == 1


def test_unknown_scenario_is_a_one_line_error_listing_valid_ones():
    with pytest.raises(ConfigError, match="valid scenarios: paper, nominal, misspecified"):
        _make(scenario="windy")
    env = _make()
    with pytest.raises(ConfigError, match="unknown scenario 'windy'"):
        env.reset(seed=1, options={"scenario": "windy"})


def test_reset_options_switch_scenario_and_render():
    env = _make(render_mode="rgb_array")
    env.reset(seed=100_000, options={"scenario": "paper"})
    assert env.unwrapped.episode.filter_cfg.r_std_nt == pytest.approx(math.sqrt(2e-3))
    for _ in range(20):
        env.step(np.zeros(2, np.float32))
    frame = env.render()
    assert frame.dtype == np.uint8 and frame.ndim == 3 and frame.shape[2] == 3


@pytest.mark.parametrize("name", SCENARIOS)
def test_scenarios_build(name):
    ep = make_episode(name, 7)
    assert np.all(np.isfinite(ep.y)) and ep.n > 5000
    assert ep.noise_var.shape == (ep.n,)


def test_misspecified_and_nonstationary_do_what_they_say():
    """``misspecified``: the filter's Q (of the drifting T_p) and R are each 10 to 100 times off
    the truth, either way, its prior on T_p is confident (1–32 nT) while the permanent field is
    hundreds of nT: a step at sample 0 for the privileged policy."""
    q_off, r_off = [], []
    for seed in range(40):
        ep = make_episode("misspecified", seed, duration_s=60.0)
        cfg = ep.filter_cfg
        q_off.append(ep.q_log10_true[1])
        r_off.append(math.log10(ep.noise_var[0] / cfg.r_std_nt**2))
        assert 1.0 <= cfg.p0_std[0] <= 10**1.5 and list(ep.step_samples) == [0]
        assert ep.q_log10_true[0] == pytest.approx(-math.log10(cfg.q_std[1] ** 2 / 1e-18))
    for off in (q_off, r_off):
        assert all(1.0 - 1e-9 <= abs(x) <= 2.0 + 1e-9 for x in off)
        assert min(off) < -1.0 and max(off) > 1.0  # both ways
    ep = make_episode("nonstationary", 3)
    levels = set(np.round(np.unique(ep.noise_var), 6))
    assert 2 <= len(levels) <= 3
    assert levels <= {round(s**2 + 1.0, 6) for s in REGIME_STD_NT}  # white² + 1 nT² FOGM
    jumps = np.abs(np.diff(ep.truth_interf, axis=0)).max(axis=1)
    assert np.sum(jumps > 10.0) >= 1  # an interference step (equipment switching on)


def test_the_drift_is_in_the_truth_and_the_fluxgate_alike(monkeypatch):
    """The temperature drift of T_p is interference: it moves the fluxgate and the truth alike,
    as a random walk whose per-sample std is the one ``q_log10_true`` gives the privileged
    policy."""
    from aeromag_env.environment import scenarios

    for name in ("misspecified", "noise_bursts"):
        ep = make_episode(name, 11)
        drift = 10 ** (ep.q_log10_true[1] / 2) * ep.filter_cfg.q_std[0]
        with monkeypatch.context() as m:
            m.setattr(
                scenarios, "_drift", lambda change, std, rng: rng.standard_normal(change.flux.shape)
            )
            still = make_episode(name, 11)  # the same draws, the walk not added
        walk = ep.truth_interf - still.truth_interf
        np.testing.assert_allclose(ep.y - still.y, walk, atol=1e-6)
        steps = np.diff(walk, axis=0)
        assert np.std(steps) == pytest.approx(drift, rel=0.05)
        assert np.abs(walk[-1]).max() > 3 * drift  # it wanders


def test_the_equipment_and_sensor_scenarios_do_what_they_say():
    cts = make_episode("calibration_then_survey", 5)
    first_line = int(np.flatnonzero(cts.flight.fields["line"] >= 1001)[0])
    assert list(cts.step_samples) == [first_line]
    jump = np.abs(cts.truth_interf[first_line] - cts.truth_interf[first_line - 1]).max()
    assert jump > 1.0  # the survey equipment switches on at the first line

    bursts = make_episode("noise_bursts", 5)
    loud = bursts.noise_var > 10**3.0  # a burst's std is at least 10^1.7 nT
    edges = np.flatnonzero(np.diff(loud.astype(int)) == 1).size + int(loud[0])
    assert 1 <= edges <= 8 and 0.01 < loud.mean() < 0.5

    worn = make_episode("degradation", 5)
    var = worn.noise_var
    onset = int(np.flatnonzero(var > var[0] + 1e-9)[0])
    assert 0.1 * worn.n <= onset + 1 <= 0.6 * worn.n + 1
    assert np.all(np.diff(var[onset:]) >= -1e-9) and var[-1] >= 10**2.4

    heavy, calm = make_episode("manoeuvre_heavy", 5), make_episode("nominal", 5)

    def swing(ep):  # the 99th percentile of the roll rate [deg/sample]
        return np.percentile(np.abs(np.diff(ep.flight.fields["ins_roll"])), 99)

    assert swing(heavy) > 1.6 * swing(calm)
    rate = np.abs(np.gradient(np.unwrap(np.deg2rad(heavy.flight.fields["ins_roll"]))))
    extra = heavy.noise_var - heavy.noise_var.min()
    assert np.corrcoef(rate, extra)[0, 1] > 0.5  # the flex noise follows the angular rate


def test_suite_draws_every_scenario_of_the_suite():
    from aeromag_env.environment.ids import SUITE

    drawn = {make_episode("suite", seed, duration_s=30.0).scenario for seed in range(60)}
    assert drawn == (set(SUITE) - {"nonstationary"}) | {"nonstationary_dense"}
    a, b = make_episode("suite", 9, duration_s=30.0), make_episode("suite", 9, duration_s=30.0)
    np.testing.assert_array_equal(a.y, b.y)


def test_dense_training_variant_adds_steps_to_the_same_flight():
    """``nonstationary_dense`` flies the same flight with the same noise regimes as
    ``nonstationary`` and only draws more interference steps (4 to 8 instead of 1 to 2)."""
    changes = []
    for seed in range(6):
        sparse = make_episode("nonstationary", seed, duration_s=300.0)
        dense = make_episode("nonstationary_dense", seed, duration_s=300.0)
        np.testing.assert_array_equal(dense.noise_var, sparse.noise_var)
        np.testing.assert_array_equal(dense.t_b, sparse.t_b)
        # the fluxgate minus the truth is the same sensor error in both
        np.testing.assert_allclose(
            dense.y - dense.truth_interf, sparse.y - sparse.truth_interf, atol=1e-9
        )
        # the truths differ by steps only: piecewise constant, changing at the dense flight's
        # steps (the sparse flight's step times are the first of them: the same draws)
        moves = np.abs(np.diff(dense.truth_interf - sparse.truth_interf, axis=0)).max(axis=1)
        changes.append(int(np.sum(moves > 1e-9)))
    assert all(4 <= c <= 8 for c in changes) and max(changes) >= 7, changes
    assert "nonstationary_dense" not in SCENARIOS  # trained on, never tabled


def test_a_graded_tp_action_scales_the_permanent_block_on_its_own():
    """Equal a_q and a_qp is the unsplit environment bitwise; a_qp moves only T_p's Q."""
    split = _make(
        scenario="nonstationary", observations=observations("log_qp_scale"), action=GRADED
    )
    plain = _make(
        scenario="nonstationary", observations=observations(), action={"mode": "absolute"}
    )
    assert split.action_space.shape == (3,) and split.observation_space.shape == (8,)
    rng = np.random.default_rng(1)
    actions = rng.uniform(-1, 1, (40, 2)).astype(np.float32)
    a = _rollout(split, 100_000, [np.r_[x, x[0]] for x in actions])
    b = _rollout(plain, 100_000, actions)
    for (obs_a, *rest_a), (obs_b, *rest_b) in zip(a[1:], b[1:], strict=True):
        np.testing.assert_array_equal(obs_a[:7], obs_b)
        # the T_p scale followed the other blocks' scale
        layout = split.unwrapped.config
        qp, q = observation_index(layout, "log_qp_scale"), observation_index(layout, "log_q_scale")
        assert obs_a[qp] == obs_a[q]
        assert rest_a[:3] == rest_b[:3]
    split.reset(seed=100_000)
    q0 = split.unwrapped.filter.qd.copy()
    split.step(np.array([0.0, 0.5, 0.6], np.float32))  # T_p at 10^6, the rest at 10^0
    qd = split.unwrapped.filter.qd
    np.testing.assert_allclose(qd[TP] / q0[TP], 1e6, rtol=1e-5)  # 0.6 in float32
    np.testing.assert_allclose(qd[INDUCED_START:] / q0[INDUCED_START:], 1.0, rtol=1e-9)
    _, _, _, _, info = split.step(np.array([0.0, 0.5, 0.6], np.float32))
    assert info["q_permanent_scale"] == pytest.approx(1e6, rel=1e-5) and info["q_scale"] == 1.0
    with pytest.raises(ValueError, match="3 finite numbers"):
        split.step(np.zeros(2, np.float32))


def test_a_gated_tp_action_sets_the_permanent_q_to_either_end_of_its_range():
    """With a gated T_p action the sign of a_qp alone picks T_p's Q: the range's top (10^10
    here) or its bottom (10^-2); a_q and a_r act as without the gate."""
    gate = {**GRADED, "permanent": "gate", "qp_log10": (-2.0, 10.0), "scale_limit": 1e10}
    env = _make(scenario="nonstationary", observations=observations("log_qp_scale"), action=gate)
    env.reset(seed=100_000)
    q0 = env.unwrapped.filter.qd.copy()
    for a_qp, log_scale in [(0.01, 10.0), (-0.01, -2.0), (0.9, 10.0), (0.0, -2.0)]:
        _, _, _, _, info = env.step(np.array([0.0, 0.5, a_qp], np.float32))
        qd = env.unwrapped.filter.qd
        np.testing.assert_allclose(qd[TP] / q0[TP], 10.0**log_scale, rtol=1e-9)
        np.testing.assert_allclose(qd[INDUCED_START:] / q0[INDUCED_START:], 1.0, rtol=1e-9)
        assert info["q_permanent_scale"] == pytest.approx(10.0**log_scale, rel=1e-9)
    with pytest.raises(ConfigError, match=r"'gate' .*needs action\.mode='absolute'"):
        _make(action={"permanent": "gate"})


def test_innovation_power_observations_follow_their_definition():
    powers = ("log_innovation_power", "log_mean_innovation_power")
    env = _make(scenario="nonstationary", observations=observations(*powers))
    assert env.observation_space.shape == (9,)
    env.reset(seed=100_003)
    f = env.unwrapped.filter
    tr_r0 = float(np.trace(f.r0))
    window = f.cfg.window
    for _ in range(60):
        obs, *_ = env.step(np.zeros(2, np.float32))
    r = f.innov[: f.k]
    r = r[np.all(np.isfinite(r), axis=1)]
    power = np.mean(np.sum(r[-window:] ** 2, axis=1))
    mean_power = np.sum(np.mean(r[-10:], axis=0) ** 2)
    column = functools.partial(observation_index, env.unwrapped.config)
    assert obs[column("log_innovation_power")] == pytest.approx(np.log10(power / tr_r0), rel=1e-5)
    assert obs[column("log_mean_innovation_power")] == pytest.approx(
        np.log10(mean_power / tr_r0), rel=1e-5
    )


def _flown_window(env, steps: int = 60):
    """The observation after ``steps`` zero actions on test flight 100 003 and the finite
    innovations of the filter's statistics window at that point."""
    env.reset(seed=100_003)
    f = env.unwrapped.filter
    for _ in range(steps):
        obs, *_ = env.step(np.zeros(env.action_space.shape, np.float32))
    r = f.innov[: f.k]
    return obs, r[np.all(np.isfinite(r), axis=1)][-f.cfg.window :]


def test_step_statistic_follows_its_definition_and_flags_a_step():
    """The two-window change statistic equals its formula on the filter's innovations, sits
    near 1 + K/(M − K) on white noise at any level, and a 5-sigma step lifts it by decades."""
    from aeromag_env.compensation.kernel_layout import INTS
    from aeromag_env.environment.statistics import step_statistic

    layout = observations("log_qp_scale", "log_step_statistic")
    env = _make(scenario="nonstationary", observations=layout, action=GRADED)
    assert env.observation_space.shape == (9,)
    obs, r = _flown_window(env)
    recent, before = r[-10:], r[:-10]
    expect = 10 * np.sum((recent.mean(0) - before.mean(0)) ** 2) / np.sum(before.var(0, ddof=1))
    column = observation_index(env.unwrapped.config, "log_step_statistic")
    assert obs[column] == pytest.approx(np.log10(expect), rel=1e-5)

    m, k = 50, 10
    ints = np.zeros(8, np.int64)
    ints[INTS.updates], ints[INTS.pos], ints[INTS.window] = m, 17, m  # a full, wrapped window
    rng = np.random.default_rng(0)
    for std in (1.0, 15.0):
        stats = [step_statistic(k, ints, std * rng.standard_normal((m, 3))) for _ in range(2000)]
        # E = (1 + k/(m−k)) · ν/(ν − 2) with ν = 3(m − k − 1) = 117 (the variance's degrees of
        # freedom); the mean of 2000 draws has a 1.8 % std, so ±5 % is a 2.7-sigma bound
        assert np.mean(stats) == pytest.approx(1.25 * 117 / 115, rel=0.05)
    buf = rng.standard_normal((m, 3))
    order = [(17 - 1 - j) % m for j in range(k)]  # the last k updates in the circular buffer
    buf[order] += 5.0
    assert step_statistic(k, ints, buf) > 100.0


def test_turn_rate_follows_its_definition_and_the_manoeuvres():
    """The turn-rate observation is log10 of the RMS of |Ṫ|/|T| over the last decision window;
    on ``manoeuvre_heavy``, whose flex noise std is proportional to the INS angular rate, it
    follows that noise (log std against it: correlation 0.91 in the same window, 0.77 in the
    next one, which the action sets R for, on this flight)."""
    env = _make(scenario="manoeuvre_heavy", observations=observations("log_turn_rate"))
    env.reset(seed=100_005)
    f, k_window = env.unwrapped.filter, env.unwrapped.config.decision_window
    column = observation_index(env.unwrapped.config, "log_turn_rate")
    noise_var = env.unwrapped.episode.noise_var
    seen, noise, coming = [], [], []
    for _ in range(400):
        obs, *_ = env.step(np.zeros(2, np.float32))
        k1 = f.k
        t, td = f.t[k1 - k_window : k1], f.td[k1 - k_window : k1]
        expect = np.sqrt(np.mean(np.sum(td**2, 1) / np.sum(t**2, 1)))
        assert obs[column] == pytest.approx(np.log10(expect), rel=1e-5)
        seen.append(obs[column])
        noise.append(0.5 * np.log10(np.mean(noise_var[k1 - k_window : k1])))
        coming.append(0.5 * np.log10(np.mean(noise_var[k1 : k1 + k_window])))
    assert np.corrcoef(seen, noise)[0, 1] > 0.85
    assert np.corrcoef(seen, coming)[0, 1] > 0.6


def test_innovation_bias_follows_its_definition_and_holds_a_missed_step():
    """The bias statistic is M |mean r|² / tr C over the statistics window's innovations; on
    white noise it sits near ν/(ν − 2) with ν = 3(M − 1) at any level, a bias of 2 noise std
    lifts it by decades, and it stays up once a step fills the whole window, where the
    two-window statistic falls back."""
    from aeromag_env.compensation.kernel_layout import INTS
    from aeromag_env.environment.statistics import innovation_bias, step_statistic

    env = _make(scenario="nonstationary", observations=observations("log_innovation_bias"))
    obs, r = _flown_window(env)
    expect = len(r) * np.sum(r.mean(0) ** 2) / np.sum(r.var(0, ddof=1))
    column = observation_index(env.unwrapped.config, "log_innovation_bias")
    assert obs[column] == pytest.approx(np.log10(expect), rel=1e-5)

    m = 50
    ints = np.zeros(8, np.int64)
    ints[INTS.updates], ints[INTS.pos], ints[INTS.window] = m, 17, m
    rng = np.random.default_rng(0)
    for std in (1.0, 15.0):
        stats = [innovation_bias(ints, std * rng.standard_normal((m, 3))) for _ in range(2000)]
        assert np.mean(stats) == pytest.approx(147 / 145, rel=0.05)  # std of the mean ~3 %
    held = 15.0 * rng.standard_normal((m, 3)) + 30.0  # a 30-nT step in 15-nT noise, window full
    assert innovation_bias(ints, held) > 100.0
    assert step_statistic(10, ints, held) < 10.0
    ints[INTS.updates] = 2
    assert np.isnan(innovation_bias(ints, held))


def test_recent_samples_sets_the_window_of_the_recent_statistics():
    """With ``recent_samples`` the step statistic (and the recent ROR and mean innovation power)
    cover that many samples instead of the decision window: at K = 5 with 10 recent samples the
    statistic is the formula over the last 10 innovations; a bad value is a config error."""
    env = _make(
        scenario="nonstationary",
        observations=observations("log_qp_scale", "log_step_statistic"),
        action=GRADED,
        decision_window=5,
        recent_samples=10,
    )
    obs, r = _flown_window(env, steps=120)
    recent, before = r[-10:], r[:-10]
    expect = 10 * np.sum((recent.mean(0) - before.mean(0)) ** 2) / np.sum(before.var(0, ddof=1))
    column = observation_index(env.unwrapped.config, "log_step_statistic")
    assert obs[column] == pytest.approx(np.log10(expect), rel=1e-5)
    with pytest.raises(ConfigError, match="recent_samples"):
        _make(recent_samples=0)


def _lag1(r: np.ndarray) -> float:
    """Lag-1 autocorrelation of the rows of ``r``, per-axis mean removed, pooled over axes."""
    c = r - r.mean(axis=0)
    return float(np.sum(c[1:] * c[:-1]) / np.sum(c * c))


def test_whiteness_without_gaps_is_bitwise_the_general_loop_and_is_the_lag1_correlation():
    """The whiteness observation has a fast loop for a window without skipped samples; it
    equals the general loop (which drops non-finite rows) bit for bit, and both equal the
    pooled lag-1 autocorrelation computed with numpy to 1e-12 (relative: summation order)."""
    from aeromag_env.environment.statistics import whiteness, whiteness_with_gaps

    rng = np.random.default_rng(3)
    r = np.cumsum(rng.standard_normal((120, 3)), axis=0) * 7.0  # correlated, not zero-mean
    for k1, window in ((120, 50), (30, 50), (3, 50), (120, 120)):
        lo = max(0, k1 - window)
        fast = whiteness(k1, window, r)
        assert fast == whiteness_with_gaps(lo, k1, k1 - lo, r)
        assert fast == pytest.approx(_lag1(r[lo:k1]), rel=1e-12)
    gaps = r.copy()
    gaps[[75, 76, 100]] = np.nan  # skipped samples: the rows around a gap become neighbours
    kept = gaps[70:120][np.all(np.isfinite(gaps[70:120]), axis=1)]
    assert whiteness(120, 50, gaps) == pytest.approx(_lag1(kept), rel=1e-12)
    assert whiteness(2, 50, r) == 0.0  # fewer than 3 rows


def test_spaces_lay_out_the_observations_and_actions_as_documented():
    """The layouts the environment's docstring states: the paper's two observations first, then
    those chosen, in their order; whiteness in [-1, 1], progress in [0, 1], the rest in ±8; a
    third action with a T_p action. The compiled step writes each observation where
    observation_positions says."""
    paper = EnvConfig()
    assert observation_names(paper) == ("log_ror", "log_qoq")
    assert action_names(paper) == ("a_q", "a_r")
    full = env_config(observations=NAMES, action={"permanent": "graded"})
    assert observation_names(full) == NAMES and len(NAMES) == 13
    assert action_names(full) == ("a_q", "a_r", "a_qp")
    powers = ("log_innovation_power", "log_mean_innovation_power")
    detector = env_config(observations=observations("log_qp_scale", *powers), action=GRADED)
    assert observation_index(detector, "log_mean_innovation_power") == 9
    step = env_config(observations=observations("log_step_statistic"))
    assert observation_index(step, "log_step_statistic") == 7
    with pytest.raises(ValueError, match="not in this layout"):
        observation_index(paper, "whiteness")
    positions = observation_positions(detector)
    assert positions.tolist() == [0, 1, 2, 3, 4, 5, 6, 7, 8, 9, -1, -1, -1]
    low, high = observation_bounds(env_config(observations=observations()))
    np.testing.assert_array_equal(low, np.float32([-8, -8, -8, -8, -1, 0, -8]))
    np.testing.assert_array_equal(high, np.float32([8, 8, 8, 8, 1, 1, 8]))
    turn = env_config(observations=observations("log_turn_rate"))
    assert observation_index(turn, "log_turn_rate") == 7
    env = _make(config=full)
    assert env.observation_space.shape == (13,) and env.action_space.shape == (3,)
