"""The learners beside PPO: their numpy exports against torch, their hyperparameter file, and
short training runs (slow) that write what the benchmark reads."""

import json

import gymnasium as gym
import numpy as np
import pytest

import aeromag_env  # noqa: F401
from aeromag_env.environment.ids import SUITE
from aeromag_env.environment.vec_env import AeroMagCompensationVecEnv
from aeromag_env.errors import AeromagError, HyperparameterError
from agents.evaluation.episodes import run_episode
from agents.policies import make_policy
from agents.policies.numpy_policy import NumpyPolicy
from agents.policies.policy_file import export_actor, write_policy
from agents.training.learners import (
    HYPERPARAMS,
    LEARNERS,
    learner_hyperparams,
    learner_settings,
    run_learner,
    selection_score,
    train_learner,
)

torch = pytest.importorskip("torch")


class _Stats:
    """A VecNormalize's observation statistics, as export_actor reads them."""

    def __init__(self, n: int, rng: np.random.Generator) -> None:
        self.obs_rms = type("rms", (), {})()
        self.obs_rms.mean = rng.normal(size=n)
        self.obs_rms.var = rng.uniform(0.5, 3.0, size=n)
        self.clip_obs, self.epsilon = 10.0, 1e-8

    def normalize(self, obs: np.ndarray) -> np.ndarray:
        z = (obs - self.obs_rms.mean) / np.sqrt(self.obs_rms.var + self.epsilon)
        return np.clip(z, -self.clip_obs, self.clip_obs).astype(np.float32)


def _model(learner: str):
    env = gym.make("AeroMagCompensation-v0", preset="general")
    torch.manual_seed(0)
    if learner == "sac":
        from stable_baselines3 import SAC

        return SAC("MlpPolicy", env, policy_kwargs={"net_arch": [32, 16]}, device="cpu", seed=0)
    if learner == "tqc":
        from sb3_contrib import TQC

        return TQC("MlpPolicy", env, policy_kwargs={"net_arch": [32]}, device="cpu", seed=0)
    from sb3_contrib import RecurrentPPO

    kwargs = {"lstm_hidden_size": 8, "net_arch": [16]}
    return RecurrentPPO("MlpLstmPolicy", env, policy_kwargs=kwargs, device="cpu", seed=0)


@pytest.mark.parametrize("learner", ["sac", "tqc"])
def test_off_policy_export_reproduces_the_deterministic_actor(tmp_path, learner):
    model = _model(learner)
    rng = np.random.default_rng(1)
    n = model.observation_space.shape[0]
    stats = _Stats(n, rng)
    path = export_actor(model, stats, tmp_path / "p.npz", {"env_kwargs": {"preset": "general"}})
    policy = NumpyPolicy.load(path)
    obs = rng.normal(size=(64, n)) * 3 + stats.obs_rms.mean
    want, _ = model.predict(stats.normalize(obs), deterministic=True)
    got, state = policy.predict(obs)
    assert state is None and not policy.recurrent
    np.testing.assert_allclose(got, want, atol=2e-6)
    assert np.abs(got).max() < 1.0  # a tanh head, not a clip


def test_recurrent_export_carries_the_lstm_state_and_resets_it(tmp_path):
    model = _model("recurrent_ppo")
    rng = np.random.default_rng(2)
    n = model.observation_space.shape[0]
    stats = _Stats(n, rng)
    path = export_actor(model, stats, tmp_path / "p.npz", {"env_kwargs": {"preset": "general"}})
    policy = NumpyPolicy.load(path)
    assert policy.recurrent
    envs, steps = 3, 6
    obs = rng.normal(size=(steps, envs, n)) * 2 + stats.obs_rms.mean
    starts = np.zeros((steps, envs), bool)
    starts[0] = True
    starts[3, 1] = True  # environment 1 starts a new episode mid-way
    torch_state = mine = None
    for k in range(steps):
        want, torch_state = model.predict(
            stats.normalize(obs[k]), state=torch_state, episode_start=starts[k], deterministic=True
        )
        got, mine = policy.predict(obs[k], state=mine, episode_start=starts[k])
        np.testing.assert_allclose(got, want, atol=2e-6)
        np.testing.assert_allclose(mine[0], torch_state[0][0], atol=2e-6)
    # memory matters: the same observation after a different history gives another action
    fresh, _ = policy.predict(obs[-1], state=None, episode_start=np.ones(envs, bool))
    assert not np.allclose(fresh, got)
    # without a state passed back, the policy continues from its own
    policy.reset()
    a0, _ = policy.predict(obs[0, 0])
    a1, _ = policy.predict(obs[0, 0])
    policy.reset()
    assert np.allclose(policy.predict(obs[0, 0])[0], a0) and not np.allclose(a0, a1)


def test_a_recurrent_policy_flies_an_episode_through_the_evaluation_path(tmp_path):
    model = _model("recurrent_ppo")
    stats = _Stats(model.observation_space.shape[0], np.random.default_rng(3))
    path = export_actor(model, stats, tmp_path / "p.npz", {"env_kwargs": {"preset": "general"}})
    env = gym.make("AeroMagCompensation-v0", scenario="paper", preset="general")
    one = run_episode(env, make_policy(f"ppo:{path}", env), 100_000)
    two = run_episode(env, make_policy(f"ppo:{path}", env), 100_000)
    assert np.isfinite(one["rmse_nt"]) and one == two  # the state is reset with the episode


def _linear(tmp_path, **meta):
    rng = np.random.default_rng(4)
    arrays = {
        "obs_mean": np.zeros(13),
        "obs_var": np.ones(13),
        "obs_clip": np.array(10.0),
        "obs_eps": np.array(1e-8),
        "w_out": rng.normal(size=(3, 13)),
        "b_out": rng.normal(size=3),
    }
    meta = {"env_kwargs": {"preset": "general"}, "head": "tanh", **meta}
    return arrays, write_policy(arrays, meta, tmp_path / "linear.npz")


def test_a_linear_rule_with_a_tanh_head_loads_and_runs(tmp_path):
    arrays, path = _linear(tmp_path)
    x = np.random.default_rng(5).normal(size=13)
    got, _ = NumpyPolicy.load(path).predict(x)
    np.testing.assert_allclose(got, np.tanh(arrays["w_out"] @ x + arrays["b_out"]), rtol=1e-6)


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"head": "sigmoid"}, "meta head must be one of clip, tanh"),
        ({"activation": "gelu"}, "meta activation must be one of tanh, relu"),
    ],
)
def test_a_policy_file_naming_an_unknown_head_or_activation_is_refused(tmp_path, change, message):
    _, path = _linear(tmp_path, **change)
    with pytest.raises(AeromagError, match=f"cannot load policy .*: {message}"):
        NumpyPolicy.load(path)


def test_an_lstm_layer_of_the_wrong_shape_or_incomplete_is_refused(tmp_path):
    arrays, _ = _linear(tmp_path)
    meta = {"env_kwargs": {"preset": "general"}}
    h = 4
    lstm = {
        "lstm_w_ih": np.zeros((4 * h, 13)),
        "lstm_w_hh": np.zeros((4 * h, h)),
        "lstm_b": np.zeros(4 * h),
    }
    ok = {**arrays, **lstm, "w_out": np.zeros((3, h)), "b_out": np.zeros(3)}
    assert NumpyPolicy.load(write_policy(ok, meta, tmp_path / "ok.npz")).recurrent
    short = {**ok, "lstm_w_ih": np.zeros((4 * h, 12))}
    with pytest.raises(AeromagError, match=r"lstm_w_ih has shape \(16, 12\); expected \(16, 13\)"):
        NumpyPolicy.load(write_policy(short, meta, tmp_path / "short.npz"))
    partial = {k: v for k, v in ok.items() if k != "lstm_b"}
    with pytest.raises(AeromagError, match=r"an LSTM layer needs .*lstm_b missing"):
        NumpyPolicy.load(write_policy(partial, meta, tmp_path / "partial.npz"))


def test_every_learner_has_checked_hyperparameters():
    for learner in LEARNERS[1:]:
        hp = learner_hyperparams(learner)
        assert (
            hp.learner == learner and hp.version == json.loads(HYPERPARAMS.read_text())["version"]
        )
        assert hp.timesteps > 0 and hp.env_kwargs == {"preset": "general"}


def test_an_unknown_key_in_a_learners_hyperparameters_is_one_line(tmp_path):
    table = json.loads(HYPERPARAMS.read_text())
    table["learners"]["sac"]["algo"]["gamme"] = 0.9
    path = tmp_path / "learners.json"
    path.write_text(json.dumps(table))
    with pytest.raises(HyperparameterError, match=r": learners.sac.algo.gamme is unknown; valid"):
        learner_hyperparams("sac", path)
    del table["learners"]["sac"]
    path.write_text(json.dumps(table))
    with pytest.raises(HyperparameterError, match="no hyperparameters for learner 'sac'"):
        learner_hyperparams("sac", path)


def test_the_flight_cache_gives_the_same_flights_and_simulates_each_once():
    plain = AeroMagCompensationVecEnv(
        4, scenario="suite", autoreset_mode="Disabled", preset="general"
    )
    cached = AeroMagCompensationVecEnv(
        4, scenario="suite", autoreset_mode="Disabled", flight_cache=2, preset="general"
    )
    seeds = [7, 8, 7, 8]
    a, _ = plain.reset(seed=seeds)
    b, _ = cached.reset(seed=seeds)
    np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(plain.flight_seeds, cached.flight_seeds)
    assert cached._simulate.cache_info().misses == 2 and cached._simulate.cache_info().hits == 2
    for _ in range(5):
        action = np.full((4, 3), 0.3, np.float32)
        np.testing.assert_array_equal(plain.step(action)[0], cached.step(action)[0])
    with pytest.raises(ValueError, match="flight_cache must be an integer ≥ 0"):
        AeroMagCompensationVecEnv(2, flight_cache=-1)


@pytest.mark.slow
@pytest.mark.parametrize("learner", LEARNERS[1:])
def test_a_quick_training_run_writes_a_policy_and_a_learning_curve(tmp_path, learner):
    summary = train_learner(learner, 0, tmp_path, quick=True)
    curve = json.loads((tmp_path / "training.json").read_text())["curve"]
    assert curve == summary["curve"] and len(curve) >= 2
    assert [p["timesteps"] for p in curve] == sorted(p["timesteps"] for p in curve)
    assert all(p["train_seconds"] <= p["seconds"] for p in curve)
    assert set(curve[0]["validation_rmse_by_scenario"]) == set(SUITE)
    kept = min(p["validation_score"] for p in curve)
    assert summary["best_validation_score"] == kept
    env = gym.make("AeroMagCompensation-v0", scenario="paper", preset="general")
    policy = make_policy(f"ppo:{tmp_path / 'policy.npz'}", env)
    assert np.isfinite(run_episode(env, policy, 100_000)["rmse_nt"])


def test_the_validation_hook_sees_every_point_of_the_curve_with_its_score(tmp_path):
    """``aeromag tune`` reports through ``on_validation``: once per validation point (at 0, 32
    and 64 steps), each the point the curve keeps, whose score selects the kept policy. A tiny
    run (64 steps of one environment, one validation flight scored against the privileged
    policy's: a score that is not the RMSE) so that it stays in the default suite."""
    hp = learner_settings("sac", quick=True, timesteps=64)
    hp = hp.with_values(n_envs=1, eval_every=32, eval_episodes=1, select_by="ratio_to_privileged")
    seen: list[dict] = []
    summary = run_learner("sac", hp, 0, tmp_path, on_validation=lambda p: seen.append(dict(p)))
    assert [p["timesteps"] for p in seen] == [0, 32, 64]
    assert seen == summary["curve"]
    scores = [selection_score(p) for p in seen]
    assert (
        scores == [p["validation_score"] for p in seen] != [p["validation_rmse_nt"] for p in seen]
    )
    assert summary["best_validation_score"] == min(scores)


def test_the_command_line_names_the_same_learners():
    from aeromag_env.cli.parser import build_parser

    train = build_parser()._subparsers._group_actions[0].choices["train"]  # type: ignore[union-attr]
    (learner,) = [a for a in train._actions if "--learner" in a.option_strings]
    assert tuple(learner.choices) == LEARNERS


def test_a_learner_other_than_ppo_refuses_a_scenario_other_than_the_suite(tmp_path, capsys):
    from aeromag_env.cli.main import main

    code = main(
        ["train", "--learner", "sac", "--scenario", "nonstationary", "--out", str(tmp_path)]
    )
    assert code == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "--scenario must be suite for learner sac" in err
    assert list(tmp_path.iterdir()) == []


@pytest.mark.slow
def test_aeromag_train_trains_another_learner_over_seeds(tmp_path, capsys):
    from aeromag_env.cli.main import main

    out = tmp_path / "runs"
    args = [
        "train",
        "--learner",
        "cmaes",
        "--seeds",
        "0-1",
        "--quick",
        "--quiet",
        "--out",
        str(out),
    ]
    assert main(args) == 0
    summary = json.loads((out / "seeds.json").read_text())
    assert summary["learner"] == "cmaes" and [r["seed"] for r in summary["seeds"]] == [0, 1]
    assert all(r["error"] is None for r in summary["seeds"])
    assert NumpyPolicy.load(out / "seed_0" / "policy.npz").meta["learner"] == "CMA-ES"
    last = [
        json.loads((out / f"seed_{k}" / "training.json").read_text())["curve"][-1] for k in (0, 1)
    ]
    assert last[0]["validation_rmse_nt"] != last[1]["validation_rmse_nt"]  # seeds differ
    assert "Training: cmaes on suite" in (out / "report.html").read_text()
