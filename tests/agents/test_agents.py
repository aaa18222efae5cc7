import json
from dataclasses import replace

import gymnasium as gym
import numpy as np
import pytest

import aeromag_env  # noqa: F401
from aeromag_env.cli.main import main
from aeromag_env.compensation.kalman import run_filter
from aeromag_env.compensation.model import MODE
from aeromag_env.environment.spaces import ACT_Q, ACT_R
from aeromag_env.errors import AeromagError, ConfigError
from agents.evaluation.episodes import evaluate, run_episode
from agents.policies import POLICIES, make_policy
from agents.policies.baselines import TunedConstantPolicy
from agents.policies.protocol import TuningPolicy
from tests._helpers import observations


def _env(scenario="paper"):
    return gym.make("AeroMagCompensation-v0", scenario=scenario)


def test_unknown_policy_is_a_one_line_error():
    with pytest.raises(ConfigError, match="unknown policy 'ppo2'; valid policies: constant, fis"):
        make_policy("ppo2", _env())


@pytest.mark.parametrize(
    "name", [p for p in POLICIES if p not in ("tuned_constant", "ppo", "general", "privileged")]
)
def test_predict_shape(name):
    env = _env()
    policy = make_policy(name, env)
    assert isinstance(policy, TuningPolicy)
    options = getattr(policy, "reset_options", {})
    obs, _ = env.reset(seed=100_000, options=dict(options) or None)
    action, _ = policy.predict(obs, episode_start=np.array([True]))
    assert action.shape == (2,) and action.dtype == np.float32 and np.all(np.abs(action) <= 1)
    if name in ("constant", "fis"):  # observation-only policies take batches (vectorised envs)
        batch, _ = policy.predict(np.zeros((4, 2), np.float32))
        assert batch.shape == (4, 2)
    else:  # privileged policies read one environment's internals
        with pytest.raises(ValueError, match="bound to one environment"):
            policy.predict(np.zeros((4, 2), np.float32))


@pytest.mark.parametrize("scenario", [pytest.param("paper", marks=pytest.mark.slow), "nominal"])
def test_fis_policy_in_the_env_is_the_fakf_filter(scenario):
    """The environment applies eq. 21 exactly as the filter's own fuzzy adaptation does: the
    FIS policy reproduces ``fakf`` (differences come from the float32 observation only)."""
    env = _env(scenario)
    got = run_episode(env, make_policy("fis", env), 100_000)["rmse_nt"]
    ep = env.unwrapped.episode
    res = run_filter(replace(ep.filter_cfg, method="fakf"), ep.y, ep.t_b, ep.tdot_b)
    half = np.arange(ep.n) >= ep.n // 2
    want = np.sqrt(np.mean((ep.truth_interf - res.interference)[half] ** 2))
    assert got == pytest.approx(want, rel=1e-5)


def test_fis_raises_r_when_ror_is_large():
    policy = make_policy("fis", _env())
    state = np.array([5])  # the step on which the FIS acts (once per statistics window)
    action, _ = policy.predict(np.array([3.0, 0.0], np.float32), state=state)
    assert action[ACT_R] > 0.5 and action[ACT_Q] == pytest.approx(0.0, abs=1e-6)  # QOQ 1: keep Q


def test_oracle_and_tuned_constant_fix_the_papers_r():
    env = _env("paper")
    base = run_episode(env, make_policy("constant", env), 100_000)["rmse_nt"]
    oracle = run_episode(env, make_policy("oracle", env), 100_000)["rmse_nt"]
    tuned = TunedConstantPolicy(env, {"paper": {"log10_q": -6.0, "log10_r": 5.0}})
    assert oracle < 0.5 * base
    assert run_episode(env, tuned, 100_000)["rmse_nt"] < 0.5 * base

    with pytest.raises(ConfigError, match="no tuned constants for scenario 'nonstationary_dense'"):
        make_policy("tuned_constant", _env("nonstationary_dense"))


def test_evaluate_results_layout_and_seed_ranges(tmp_path):
    with pytest.raises(AeromagError, match="must be ≥ 100000"):
        evaluate("nominal", ["fis"], [5])
    res = evaluate("nominal", ["constant", "fis"], [100_000, 100_001, 100_002])
    row = res["policies"]["constant"]
    assert {
        "rmse_nt_mean",
        "rmse_nt_ci95",
        "reward_mean",
        "divergences",
        "log_ror_abs_median",
        "diff_vs_fis_nt_mean",
        "diff_vs_fis_ci95",
    } <= set(row)
    assert res["policies"]["fis"]["diff_vs_fis_nt_mean"] == 0.0
    lo, hi = row["rmse_nt_ci95"]
    assert lo <= row["rmse_nt_mean"] <= hi


def test_evaluate_cli(tmp_path, capsys):
    args = [
        "evaluate",
        "--scenario",
        "paper",
        "--policies",
        "constant,fis",
        "--episodes",
        "2",
        "--out",
        str(tmp_path),
        "--quiet",
    ]
    assert main(args) == 0
    res = json.loads((tmp_path / "results.json").read_text())
    assert res["seeds"] == [100_000, 100_001]
    assert (tmp_path / "evaluation.png").stat().st_size > 10_000
    assert main([*args[:3], "--policies", "fis,bogus", "--out", str(tmp_path / "x")]) == 2
    assert "--policies takes names of constant, fis" in capsys.readouterr().err
    assert main(["evaluate", "--scenario", "windy", "--out", str(tmp_path / "y")]) == 2
    assert main(["evaluate", "--seed-start", "5", "--out", str(tmp_path / "z"), "--quiet"]) == 2


def test_innovation_detector_raises_permanent_q_only_on_a_large_mean_innovation():
    from aeromag_env.environment.config import PRESETS, env_config
    from aeromag_env.environment.spaces import ACT_QP, observation_index
    from agents.policies.baselines import InnovationDetectorPolicy

    action = {
        "mode": "absolute",
        "permanent": "graded",
        "q_log10": (-4.0, 4.0),
        "r_log10": (-1.0, 3.0),
        "qp_log10": (-2.0, 10.0),
    }
    powers = ("log_innovation_power", "log_mean_innovation_power")
    kw = {"observations": observations("log_qp_scale", *powers), "action": action}
    tr_r0 = 3 * 1.5**2  # nT², the default R(0)
    obs = np.zeros((3, 10), np.float32)
    column = observation_index(env_config(**kw), "log_mean_innovation_power")
    obs[:, column] = np.log10(np.array([19.0, 21.0, 60.0]) ** 2 / tr_r0)  # |mean r| 19, 21, 60 nT
    actions, _ = InnovationDetectorPolicy(env_config(**kw)).predict(obs)
    np.testing.assert_allclose(actions[:, ACT_Q], 0.0, atol=1e-7)  # Q at 10^0 in (-4, 4)
    np.testing.assert_allclose(actions[:, ACT_R], 0.5, atol=1e-7)  # R at 10^2 in (-1, 3)
    np.testing.assert_allclose(actions[:, ACT_QP], [-2 / 3, 1.0, 1.0], atol=1e-6)  # 10^0, 10^10
    gate = {**action, "permanent": "gate"}
    gated, _ = InnovationDetectorPolicy(env_config(**{**kw, "action": gate})).predict(obs[0])
    assert gated[ACT_QP] == -1.0
    assert InnovationDetectorPolicy(PRESETS["nonstationary"]).raise_qp == 1.0  # its preset
    for refused in (  # without the observation it reads, without a T_p action, relative
        {**kw, "observations": observations("log_qp_scale")},
        {"observations": observations(*powers), "action": {"mode": "absolute"}},
        {**kw, "action": {**action, "mode": "relative"}},
    ):
        with pytest.raises(ConfigError, match="innovation_detector needs the observation log_"):
            InnovationDetectorPolicy(env_config(**refused))


def test_the_privileged_policy_acts_on_the_true_noise_and_the_steps():
    """In its own layout (policy_env_kwargs): T_p's Q raised exactly in the decision window
    that holds a step and the one after, R at the true noise variance of the coming window;
    refused elsewhere."""
    from agents.policies import policy_env_kwargs
    from agents.policies.baselines import PrivilegedPolicy

    with pytest.raises(ConfigError, match=r"privileged needs action\.mode='absolute' and a T_p"):
        PrivilegedPolicy(_env())
    env = gym.make(
        "AeroMagCompensation-v0", scenario="nonstationary", **policy_env_kwargs("privileged")
    )
    obs, _ = env.reset(seed=100_000)
    policy, inner = make_policy("privileged", env), env.unwrapped
    steps, raised = inner.episode.step_samples, []
    assert steps.size >= 1
    done = False
    while not done:
        k = inner.filter.k
        action, _ = policy.predict(obs)
        assert action.shape == (3,)
        if action[2] > 0:
            raised.append(k)
        r_log10 = -2.0 + (action[1] + 1.0) / 2.0 * 9.0  # absolute_r_log10 = (-2, 7)
        coming = inner.episode.noise_var[k : k + 10].max()  # the window's loudest sample
        want = np.log10(coming / np.mean(np.diag(inner.filter.r0)))
        assert r_log10 == pytest.approx(want, abs=1e-5)
        obs, _, terminated, truncated, _ = env.step(action)
        done = terminated or truncated
    want_raised = sorted({w for s in steps for w in (s - s % 10, s - s % 10 + 10)})
    assert raised == want_raised


def test_the_privileged_floor_on_r_holds_on_its_scenarios_only():
    """With ``r_floor`` the teacher's R is the unfloored one where that is above the floor and
    the floor elsewhere, on the scenarios named; on the others it is unchanged."""
    from agents.policies import policy_env_kwargs
    from agents.policies.baselines import PrivilegedPolicy

    for scenario, floor in (("noise_bursts", 2.0), ("degradation", None)):
        env = gym.make(
            "AeroMagCompensation-v0", scenario=scenario, **policy_env_kwargs("privileged")
        )
        obs, _ = env.reset(seed=100_000)
        plain = PrivilegedPolicy(env)
        floored = PrivilegedPolicy(env, r_floor={"noise_bursts": 2.0})
        held = below = 0
        for _ in range(300):
            a, b = plain.predict(obs)[0], floored.predict(obs)[0]
            r_log10 = -2.0 + (a[1] + 1.0) / 2.0 * 9.0  # absolute_r_log10 = (-2, 7)
            want = a[1] if floor is None or r_log10 >= floor else 2.0 * (floor + 2.0) / 9.0 - 1.0
            assert b[1] == pytest.approx(want, abs=1e-9)
            assert np.array_equal(np.delete(a, 1), np.delete(b, 1))
            held += floor is not None and r_log10 < floor
            below += r_log10 < 2.0
            obs, *_ = env.step(a)
        assert below > 0  # the floor was tested where it binds
        assert (held > 0) == (floor is not None)


def _env_state(env):
    """What a policy must not change: the configuration, the filter's mode, progress and
    arrays, the flight's truth, the cumulative scales."""
    from aeromag_env.compensation.arrays import CORE_ARRAYS

    inner = env.unwrapped
    f, ep = inner.filter, inner.episode
    plain = (inner.config, int(f.mode), f.k, inner.log_scales, inner.scenario)
    arrays = [getattr(f, name).copy() for name in CORE_ARRAYS]
    return plain, [*arrays, ep.noise_var.copy(), ep.step_samples.copy()]


@pytest.mark.parametrize("name", ["oracle", "privileged", "tuned_constant", "sage_husa"])
def test_the_privileged_policies_leave_the_environment_untouched(name):
    """Predicting reads the environment (its truth, its filter's progress) and changes none of
    it: the state is equal before and after predictions without a step."""
    from agents.policies import policy_env_kwargs

    env = gym.make("AeroMagCompensation-v0", scenario="nominal", **policy_env_kwargs(name))
    policy = make_policy(name, env)
    obs, _ = env.reset(seed=100_000, options=dict(getattr(policy, "reset_options", {})) or None)
    for steps in (0, 3):  # right after reset, and within the flight
        for _ in range(steps):
            obs, *_ = env.step(policy.predict(obs)[0])
        plain, arrays = _env_state(env)
        for _ in range(5):
            policy.predict(obs)
        plain_after, arrays_after = _env_state(env)
        assert plain_after == plain
        assert len(arrays) > 5
        for before, after in zip(arrays, arrays_after, strict=True):
            np.testing.assert_array_equal(after, before)


def test_the_flight_truth_is_read_only():
    from aeromag_env.environment.truth import flight_truth

    env = gym.make("AeroMagCompensation-v0", scenario="nonstationary")
    env.reset(seed=100_000)
    truth = flight_truth(env)
    with pytest.raises(ValueError, match="read-only"):
        truth.noise_var[0] = 0.0
    with pytest.raises(ValueError, match="read-only"):
        truth.step_samples[...] = 0
    with pytest.raises(AttributeError):
        truth.sample = 5  # type: ignore[misc]
    assert env.unwrapped.episode.noise_var.flags.writeable  # the environment's own arrays stay


def test_a_classical_policy_asks_for_its_filter_method():
    """sage_husa runs the environment's filter in its own method, which the environment offers
    as a reset option; without it the policy refuses in one line, never switching the filter."""
    env = _env()
    policy = make_policy("sage_husa", env)
    obs, _ = env.reset(seed=100_000)
    with pytest.raises(ConfigError, match="needs the environment reset with"):
        policy.predict(obs)
    assert env.unwrapped.filter.mode == MODE[env.unwrapped.episode.filter_cfg.method]  # as it was
    env.reset(seed=100_000, options={"filter_method": "sage-husa"})
    assert env.unwrapped.filter.mode == MODE["sage-husa"] != MODE["kf"]
    with pytest.raises(ConfigError, match="method must be one of"):
        env.reset(seed=100_000, options={"filter_method": "bogus"})
