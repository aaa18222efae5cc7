"""The adaptive filters as policies of ``aeromag evaluate`` (``vbakf``, ``vbakf_pr``, ``imm``) and
the scenario-blind ``tuned_constant_suite``: each runs, runs what it says inside the environment's
compiled step (single and vector), counts its divergences, reads no scenario, and refuses what it
cannot do in one line."""

from __future__ import annotations

import json
from dataclasses import replace
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import aeromag_env  # noqa: F401  (registers the environment)
from aeromag_env.compensation.kalman import run_filter
from aeromag_env.compensation.model import MODE
from aeromag_env.environment.config import ActionSpec
from aeromag_env.environment.env import AeroMagCompensationEnv
from aeromag_env.errors import AeromagError, ConfigError
from agents.evaluation.episodes import run_episode
from agents.policies import POLICIES, make_policy
from agents.policies.baselines import (
    ClassicalPolicy,
    TargetScalePolicy,
    TunedConstantSuitePolicy,
    neutral_action,
)
from agents.policies.tuned_table import SUITE_TABLE, load_suite
from tests._helpers import assert_one_line_error

#: The new adaptive-filter policies and the filter method each runs.
FILTER_POLICIES = {"vbakf": "vbakf", "vbakf_pr": "vbakf-pr", "imm": "imm"}
SEED = 100_000


def _env(scenario: str = "nominal", **kw: Any) -> Any:
    return gym.make("AeroMagCompensation-v0", scenario=scenario, **kw)


def test_the_new_policies_are_in_the_registry():
    assert {*FILTER_POLICIES, "tuned_constant_suite"} <= set(POLICIES)


@pytest.mark.parametrize("name", FILTER_POLICIES)
def test_an_adaptive_filter_policy_runs_its_method_in_the_environment(name):
    """The environment's episode under the policy is the offline filter of that method on the
    same flight: same RMSE over the scored half (the neutral action leaves Q and R alone, and
    the compiled step advances the same loop window by window)."""
    env = _env()
    policy = make_policy(name, env)
    got = run_episode(env, policy, SEED)
    inner = env.unwrapped
    assert inner.filter.mode == MODE[FILTER_POLICIES[name]] != MODE["kf"]
    ep = inner.episode
    res = run_filter(replace(ep.filter_cfg, method=FILTER_POLICIES[name]), ep.y, ep.t_b, ep.tdot_b)
    half = np.arange(ep.n) >= ep.n // 2
    want = np.sqrt(np.mean((ep.truth_interf - res.interference)[half] ** 2))
    # rel 1e-9: the same compiled loop; only the order of the squared errors' sums differs
    assert got["rmse_nt"] == pytest.approx(want, rel=1e-9)
    assert got["divergences"] == 0
    kf = run_filter(ep.filter_cfg, ep.y, ep.t_b, ep.tdot_b).interference
    assert not np.allclose(kf[half], res.interference[half])  # the method is not the plain KF


@pytest.mark.parametrize("method", FILTER_POLICIES.values())
def test_a_vector_environment_runs_the_method_it_is_reset_with(method):
    """``reset(options={"filter_method": m})`` of the vector environment: environment i is the
    single environment with that option, bitwise; the method holds after an autoreset."""
    vec: Any = gym.make_vec(
        "AeroMagCompensation-v0",
        num_envs=2,
        vectorization_mode="vector_entry_point",
        scenario="nominal",
    )
    vec.reset(seed=SEED, options={"filter_method": method})
    assert list(vec.unwrapped.filters.mode) == [MODE[method]] * 2
    done, rmse = np.zeros(2, bool), np.full(2, np.nan)
    while not done.all():
        _, _, term, trunc, info = vec.step(np.zeros((2, 2), np.float32))
        ended = (term | trunc) & ~done
        rmse[ended] = info["episode_rmse_nt"][ended]
        done |= term | trunc
    for i in range(2):
        single = _env()
        single.reset(seed=SEED + i, options={"filter_method": method})
        ended1 = False
        while not ended1:
            _, _, term1, trunc1, last = single.step(np.zeros(2, np.float32))
            ended1 = term1 or trunc1
        assert rmse[i] == last["episode_rmse_nt"]
    vec.step(np.zeros((2, 2), np.float32))  # the autoreset: new flights, same method
    assert list(vec.unwrapped.filters.mode) == [MODE[method]] * 2
    with pytest.raises(ConfigError, match="method must be one of"):
        vec.reset(seed=SEED, options={"filter_method": "bogus"})
    vec.close()


@pytest.mark.parametrize("method", FILTER_POLICIES.values())
def test_a_diverged_adaptive_filter_is_counted(method):
    env = _env()
    env.reset(seed=SEED, options={"filter_method": method})
    env.unwrapped.filter.qd[:] = 1e300  # a covariance that overflows on the next predict
    _, reward, terminated, _, info = env.step(np.zeros(2, np.float32))
    assert terminated and reward == -10.0 and info["divergences"] == 1


def test_an_adaptive_filter_policy_refuses_a_filter_it_does_not_run():
    env = _env()
    policy = make_policy("vbakf", env)
    obs, _ = env.reset(seed=SEED)  # without the policy's reset option: the plain KF
    with pytest.raises(ConfigError, match="needs the environment reset with"):
        policy.predict(obs)
    with pytest.raises(ConfigError, match="no adaptive-filter policy for method 'kf'"):
        ClassicalPolicy("kf", env)


def test_the_neutral_action_holds_q_and_r_in_either_action_mode():
    """Relative mode: zeros; absolute mode: the action of log10 scale 0, which the environment
    maps back to scales of exactly 1 (to the float32 rounding of the action)."""
    assert list(neutral_action(ActionSpec(), "vbakf")) == [0.0, 0.0]
    absolute = {"mode": "absolute", "q_log10": (-4.0, 4.0), "r_log10": (-1.0, 3.0)}
    env = _env(action=absolute)
    policy = ClassicalPolicy("imm", env)
    obs, _ = env.reset(seed=SEED, options=dict(policy.reset_options))
    _, _, _, _, info = env.step(policy.predict(obs)[0])
    # 1e-6: the float32 action's rounding, times the ranges' 4-decade half-widths
    assert info["q_scale"] == pytest.approx(1.0, rel=1e-5)
    assert info["r_scale"] == pytest.approx(1.0, rel=1e-5)
    with pytest.raises(ConfigError, match="must contain 0"):
        make_policy("vbakf", _env(action={"mode": "absolute", "r_log10": (1.0, 3.0)}))
    gate = {"mode": "absolute", "permanent": "gate"}
    with pytest.raises(ConfigError, match="permanent='gate'"):
        make_policy("imm", _env(action=gate))


# --- tuned_constant_suite ------------------------------------------------------------------------


def test_the_shipped_suite_constant_says_where_it_came_from():
    stored = load_suite()
    assert {"command", "date", "seeds", "scenarios", "objective", "grid_rmse_nt"} <= set(stored)
    assert max(stored["seeds"]) < 50_000  # training seeds only
    assert stored["log10_q"] in stored["grid_log10_q"]
    assert stored["log10_r"] in stored["grid_log10_r"]


class _Blind(AeroMagCompensationEnv):
    """An environment whose scenario a policy may not read."""

    @property
    def scenario(self) -> str:
        raise AssertionError("the policy read the scenario")


@pytest.mark.parametrize("name", ["tuned_constant_suite", *FILTER_POLICIES])
def test_the_new_policies_read_no_scenario(name):
    """Built and flown on an environment whose ``scenario`` raises; the per-scenario
    ``tuned_constant`` fails there (so the check can fail)."""
    env = _Blind(scenario="noise_bursts")
    policy = make_policy(name, env)
    assert np.isfinite(run_episode(env, policy, SEED)["rmse_nt"])
    with pytest.raises(AssertionError, match="read the scenario"):
        make_policy("tuned_constant", env)


def test_the_suite_constant_acts_alike_on_every_scenario_and_holds_its_scales():
    """The same actions on two scenarios, and the same flight as the truth-reading
    :class:`TargetScalePolicy` steering to the same scales (it counts its own actions as the
    environment applies them)."""
    actions = {}
    for scenario in ("paper", "noise_bursts"):
        env = _env(scenario)
        policy = TunedConstantSuitePolicy(env.unwrapped.config.action, log10_q=-3.0, log10_r=2.0)
        steps: list[dict] = []
        ours = run_episode(env, policy, SEED, trace=steps)
        actions[scenario] = [(s["q_scale"], s["r_scale"]) for s in steps[:40]]
        truth = TargetScalePolicy(env, -3.0 * np.log(10.0), 2.0 * np.log(10.0))
        assert ours["rmse_nt"] == run_episode(env, truth, SEED)["rmse_nt"]
        q, r = steps[-1]["q_scale"], steps[-1]["r_scale"]
        assert q == pytest.approx(1e-3, rel=1e-9) and r == pytest.approx(1e2, rel=1e-9)
    assert actions["paper"] == actions["noise_bursts"]


def test_the_suite_constant_takes_a_batch_and_restarts_at_an_episode_start():
    # R at 10^0.5: ln(10^0.5) / ln(s_max = 2) = 1.66 steps, one whole then 0.66
    policy = TunedConstantSuitePolicy(ActionSpec(), log10_q=0.0, log10_r=0.5)
    first, state = policy.predict(np.zeros((3, 2), np.float32), episode_start=np.ones(3, bool))
    assert first.shape == (3, 2) and np.all(first[:, 1] == 1.0) and np.all(first[:, 0] == 0.0)
    again, _ = policy.predict(np.zeros((3, 2)), state, np.array([True, False, False]))
    assert again[0, 1] == 1.0  # env 0 starts over
    assert again[1, 1] == pytest.approx(0.5 * np.log(10.0) / np.log(2.0) - 1.0, rel=1e-6)


@pytest.mark.parametrize(
    "action, kw, words",
    [
        ({"permanent": "graded"}, {}, "action.permanent must be 'joint'"),
        ({}, {"log10_q": 9.0, "log10_r": 0.0}, "log10_q = 9 is out of the action's reach"),
        ({"mode": "absolute"}, {"log10_q": 0.0, "log10_r": 4.0}, "log10_r = 4 is out"),
        ({}, {"log10_q": float("nan"), "log10_r": 0.0}, "must be finite"),
    ],
)
def test_the_suite_constant_refuses_what_it_cannot_hold(action, kw, words):
    with pytest.raises(ConfigError) as e:
        TunedConstantSuitePolicy(ActionSpec(**action), **kw)
    assert_one_line_error(e, words)


def test_a_broken_suite_file_is_a_one_line_error(tmp_path):
    path = tmp_path / "suite.json"
    path.write_text(json.dumps({"log10_q": None, "log10_r": 1.0}))
    with pytest.raises(AeromagError) as e:
        load_suite(path)
    assert_one_line_error(e, "needs finite log10_q and log10_r")
    with pytest.raises(AeromagError, match="cannot read the suite's tuned constant"):
        load_suite(tmp_path / "absent.json")
    assert SUITE_TABLE.exists()


def test_the_suite_search_minimises_the_mean_log_rmse_over_scenarios():
    """On a 2 × 2 grid of two scenarios, one training flight each: the chosen cell is the
    argmin of the mean of ln(mean RMSE), its RMSE per scenario the grid's, its ratios those to
    each scenario's best cell; test seeds are refused."""
    from agents.search.tuned_constant import tune_constant_suite

    grid = {"log10_q": (-8.0, 0.0), "log10_r": (-2.0, 3.0)}
    found = tune_constant_suite(["paper", "nominal"], [0], grid["log10_q"], grid["log10_r"])
    grids = {s: np.array(g) for s, g in found["grid_rmse_nt"].items()}
    score = np.mean([np.log(g) for g in grids.values()], axis=0)
    i, j = np.unravel_index(np.argmin(score), score.shape)
    assert (found["log10_q"], found["log10_r"]) == (grid["log10_q"][i], grid["log10_r"][j])
    for s, g in grids.items():
        assert found["rmse_nt"][s] == g[i, j]
        assert found["ratio_to_own_best"][s] == pytest.approx(g[i, j] / g.min(), rel=1e-12)
    with pytest.raises(AeromagError, match="must be training seeds"):
        tune_constant_suite(["paper"], [100_000], grid["log10_q"], grid["log10_r"])


def test_the_suite_choice_skips_cells_the_environment_cannot_hold():
    """A cell beyond the action's reach is flown clamped at the limit; it is never chosen, even
    when it scores best (here Q × 1e-10 with a reach of 8 decades), and ties go to the first."""
    from agents.search.tuned_constant import choose_suite

    q, r = (-10.0, -8.0, 0.0), (0.0, 1.0)
    grids = {
        "a": np.array([[1.0, 2.0], [1.5, 2.0], [3.0, 3.0]]),
        "b": np.array([[1.0, 1.0], [1.5, 1.5], [1.0, 1.0]]),
    }
    found = choose_suite(grids, q, r, reach=8.0)
    assert (found["log10_q"], found["log10_r"]) == (-8.0, 0.0)
    assert found["ratio_to_own_best"] == {"a": 1.5, "b": 1.5} and found["worst_ratio"] == 1.5
    assert choose_suite(grids, q, r, reach=10.0)["log10_q"] == -10.0
    with pytest.raises(AeromagError, match="no cell of the grid is within reach"):
        choose_suite(grids, (-10.0, -9.0, 9.0), r, reach=8.0)
