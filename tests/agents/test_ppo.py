import json

import gymnasium as gym
import numpy as np
import pytest

import aeromag_env  # noqa: F401
from aeromag_env.cli.main import main
from aeromag_env.environment.config import env_config
from aeromag_env.environment.ids import SUITE
from aeromag_env.environment.spaces import ACT_R
from aeromag_env.errors import AeromagError
from agents.policies import DEFAULT_PPO, make_policy, policy_env_kwargs
from agents.policies.numpy_policy import NumpyPPOPolicy
from agents.training.hyperparameters import Pretrain
from agents.training.ppo import (
    HYPERPARAMS,
    export_policy,
    load_hyperparams,
    make_ppo,
    make_training_env,
    train_ppo,
)


@pytest.mark.slow
def test_numpy_export_reproduces_sb3_actions(tmp_path):
    from stable_baselines3 import PPO

    hp = load_hyperparams("nonstationary").with_values(n_envs=2, n_steps=64, batch_size=64)
    venv = make_training_env("nonstationary", hp, seed=0)
    model = PPO(
        "MlpPolicy",
        venv,
        n_steps=64,
        batch_size=64,
        seed=0,
        device="cpu",
        policy_kwargs={"net_arch": [64, 64]},
    )
    model.learn(256)  # non-trivial weights and observation statistics
    path = export_policy(model, venv, tmp_path / "p.npz", {"env_kwargs": dict(hp.env_kwargs)})
    policy = NumpyPPOPolicy.load(path)
    obs = np.random.default_rng(0).uniform(-3, 3, (50, venv.observation_space.shape[0]))
    ours, _ = policy.predict(obs.astype(np.float32))
    theirs, _ = model.predict(venv.normalize_obs(obs.astype(np.float32)), deterministic=True)
    # torch runs float32, the export float64: agreement to float32 round-off
    np.testing.assert_allclose(ours, np.clip(theirs, -1, 1), atol=1e-5)
    one, _ = policy.predict(obs[0].astype(np.float32))
    assert one.shape == venv.action_space.shape  # (3,): the shipped design splits Q


@pytest.mark.parametrize("kind", ["batched", "dummy"])
def test_train_scenario_trains_on_its_own_scenario_only(kind):
    """``train_scenario`` sets the training environments' scenario (both vectorisations); an
    unknown one is a one-line error."""
    hp = load_hyperparams("nonstationary").with_values(n_envs=2, vec_env=kind, prefetch=False)
    venv = make_training_env(
        "nonstationary", hp.with_values(train_scenario="nonstationary_dense"), 0
    )
    venv.reset()
    inner = venv.venv
    scenarios = inner.venv.scenarios if kind == "batched" else inner.get_attr("_scenario")
    assert list(scenarios) == ["nonstationary_dense"] * 2
    venv.close()
    with pytest.raises(AeromagError, match="train_scenario must be a scenario name: paper"):
        make_training_env("nonstationary", hp.with_values(train_scenario="windy"), 0)


def test_linear_learning_rate_schedule_reaches_sb3_and_bad_rates_are_one_line_errors():
    hp = load_hyperparams("nonstationary").with_values(n_envs=2, prefetch=False)
    venv = make_training_env("nonstationary", hp, 0)
    model = make_ppo(venv, hp.with_values(learning_rate="lin_0.001"), seed=0)
    assert model.lr_schedule(1.0) == pytest.approx(1e-3)
    assert model.lr_schedule(0.25) == pytest.approx(2.5e-4)
    assert make_ppo(venv, hp, seed=0).lr_schedule(0.25) == pytest.approx(hp.learning_rate)
    for bad in ("lin_fast", "lin_-1", "cos_0.001", 0.0, True):
        with pytest.raises(AeromagError, match="learning_rate"):
            make_ppo(venv, hp.with_values(learning_rate=bad), seed=0)
    venv.close()


def test_loading_is_pickle_free_and_errors_are_one_line(tmp_path):
    bad = tmp_path / "bad.npz"
    np.savez(bad, obs_mean=np.array([object()], dtype=object))
    with pytest.raises(AeromagError, match="cannot load policy"):
        NumpyPPOPolicy.load(bad)
    with pytest.raises(AeromagError, match="cannot load policy"):
        NumpyPPOPolicy.load(tmp_path / "missing.npz")


def test_train_quick_then_resume_then_evaluate(tmp_path):
    out = tmp_path / "ppo"
    args = ["train", "--quick", "--out", str(out), "--quiet", "--timesteps"]
    assert main([*args, "512"]) == 0
    first = (out / "training.json").read_bytes()
    assert main([*args, "512"]) == 0  # the request's total reached: nothing trained
    assert (out / "training.json").read_bytes() == first
    assert main([*args, "1024"]) == 0  # resumes from the checkpoint up to the new total
    summary = json.loads((out / "training.json").read_text())
    assert json.loads(first)["timesteps"] < 1024 <= summary["timesteps"]
    steps = [c["timesteps"] for c in summary["curve"]]
    assert steps == sorted(set(steps))  # one validation per point of the learning curve
    name = f"ppo:{out / 'policy.npz'}"
    assert env_config(**policy_env_kwargs(name)).action.mode == "absolute"
    env = gym.make("AeroMagCompensation-v0", scenario="nonstationary", **policy_env_kwargs(name))
    obs, _ = env.reset(seed=100_000)
    action, _ = make_policy(name, env).predict(obs)
    assert action.shape == env.action_space.shape and np.all(np.abs(action) <= 1)


@pytest.mark.skipif(not DEFAULT_PPO.exists(), reason="the trained policy is not shipped yet")
def test_shipped_policy_runs_without_torch_imports():
    env = gym.make("AeroMagCompensation-v0", scenario="nonstationary", **policy_env_kwargs("ppo"))
    obs, _ = env.reset(seed=100_000)
    action, _ = make_policy("ppo", env).predict(obs)
    assert action.dtype == np.float32 and np.all(np.abs(action) <= 1)


def test_discounted_returns_restart_after_an_episode_end():
    from agents.training.imitation import _discounted

    rewards = np.array([[1.0, 2.0], [1.0, 2.0], [1.0, 2.0]])
    dones = np.array([[False, True], [False, False], [False, False]])
    g = _discounted(rewards, dones, 0.5)
    np.testing.assert_allclose(g[:, 0], [1.75, 1.5, 1.0])  # 1 + 0.5 + 0.25, …
    np.testing.assert_allclose(g[:, 1], [2.0, 3.0, 2.0])  # the first episode ends at t = 0


@pytest.mark.slow
def test_behaviour_clone_makes_the_actor_imitate_the_detector():
    """After pretraining on the demonstrator's rollouts the actor's Q and R actions are close to
    the demonstrator's on states it never saw (fresh rollouts), where the untrained ones are not
    (the rare T_p raises are what PPO then trains on)."""
    import torch

    from agents.policies.baselines import InnovationDetectorPolicy
    from agents.training.imitation import behaviour_clone

    torch.manual_seed(0)
    hp = load_hyperparams("nonstationary").with_values(
        n_envs=4,
        prefetch=False,
        pretrain=Pretrain(threshold_nt=20.0, steps=4000, epochs=50),
    )
    venv = make_training_env("nonstationary", hp, seed=0)
    model = make_ppo(venv, hp, seed=0)
    demo = InnovationDetectorPolicy(env_config(**hp.env_kwargs))

    def gap() -> float:
        obs = venv.get_original_obs()
        errors = []
        for _ in range(100):
            target = demo.predict(obs)[0]
            mean, _ = model.predict(venv.normalize_obs(obs), deterministic=True)
            errors.append(np.abs(mean[:, :2] - target[:, :2]).mean())
            venv.step(target)
            obs = venv.get_original_obs()
        return float(np.mean(errors))

    venv.reset()
    before = gap()
    behaviour_clone(model, venv, hp)
    after = gap()
    assert before > 0.2 and after < 0.05, (before, after)  # mean |error| of Q, R [action units]
    venv.close()


def test_training_setup_changes_no_result_and_restores_torch():
    """Training's speed-ups — torch.distributions' argument checks off, one thread, Adam's
    foreach step — leave what PPO learns bitwise as SB3's defaults on one thread (the thread
    count itself changes float round-off), and the process's torch settings are restored."""
    import torch
    from stable_baselines3 import PPO
    from torch.distributions import Distribution, Normal

    from agents.training.ppo import _ppo_kwargs, training_torch

    hp = load_hyperparams("nonstationary").with_values(
        n_envs=2, n_steps=64, batch_size=64, vec_env="batched", prefetch=False
    )
    venv = lambda: make_training_env("nonstationary", hp, seed=3)  # noqa: E731

    def learned(model: PPO) -> list[np.ndarray]:
        model.learn(256)
        return [p.detach().numpy().copy() for p in model.policy.parameters()]

    kwargs = _ppo_kwargs(hp)
    del kwargs["policy_kwargs"]["optimizer_kwargs"]  # SB3's own Adam
    threads, checks = torch.get_num_threads(), Distribution._validate_args
    torch.set_num_threads(1)
    try:
        reference = learned(PPO("MlpPolicy", venv(), seed=3, device="cpu", **kwargs))
    finally:
        torch.set_num_threads(threads)
    with training_torch():
        assert torch.get_num_threads() == 1
        Normal(torch.zeros(1), -torch.ones(1))  # a negative scale: no check, no error
        model = make_ppo(venv(), hp, seed=3)
        assert model.policy.optimizer.defaults["foreach"]
        ours = learned(model)
    for a, b in zip(reference, ours, strict=True):
        np.testing.assert_array_equal(a, b)
    assert (torch.get_num_threads(), Distribution._validate_args) == (threads, checks)
    with pytest.raises(ValueError):  # checks on again (torch's default, outside python -O)
        Normal(torch.zeros(1), -torch.ones(1))


@pytest.mark.slow
def test_imitating_the_privileged_policy_follows_the_student_and_learns_the_teacher():
    """DAgger with the privileged teacher (the general policy's pretraining): a later round's
    flights go where the student's actions take them, labelled with what the teacher would do
    there; after the rounds the student acts much closer to the teacher on the teacher's own
    flights (from the observations alone)."""
    import torch

    from agents.training.imitation import _privileged_rollouts, behaviour_clone

    torch.manual_seed(0)
    hp = load_hyperparams("suite").with_values(n_envs=2, prefetch=False)
    venv = make_training_env("suite", hp, seed=0)
    zeros = lambda obs: np.zeros((obs.shape[0], 3), np.float32)  # noqa: E731
    obs, labels, _, _, drawn = _privileged_rollouts(venv, hp, "suite", 400, zeros)
    # the flights followed the zero actions: the same as flying them with zero actions alone
    env = gym.make("AeroMagCompensation-v0", scenario="suite", **hp.env_kwargs)
    first = env.reset(seed=next(iter(_first_seed())))[0]
    np.testing.assert_array_equal(obs[0][0], first)
    assert drawn[0][0] == env.unwrapped.episode.scenario != "suite"  # the scenario drawn
    flown = [env.step(np.zeros(3, np.float32))[0] for _ in range(5)]
    np.testing.assert_array_equal(np.stack([o[0] for o in obs[1:6]]), np.stack(flown))
    assert np.abs(np.concatenate(labels)).max() > 0.5  # the teacher would have acted

    model = make_ppo(venv, hp, seed=0)
    held_out = _privileged_rollouts(venv, hp, "suite", 2000, None)  # teacher's own flights

    def gap() -> float:
        x = venv.normalize_obs(np.concatenate(held_out[0]))
        mean, _ = model.policy.predict(x, deterministic=True)
        return float(np.abs(np.clip(mean, -1, 1) - np.concatenate(held_out[1])).mean())

    before = gap()
    hp = hp.with_values(pretrain={"steps": 3000, "epochs": 20, "dagger_rounds": 2})
    behaviour_clone(model, venv, hp, "suite")
    assert gap() < 0.6 * before, (before, gap())
    venv.close()


def test_the_dagger_teacher_keeps_r_above_its_floor_on_the_named_scenarios():
    """``pretrain.teacher_r_floor`` reaches the teacher: on noise_bursts flights every R label
    is at or above the floor, and the same flights without it have labels below."""
    from agents.training.imitation import _privileged_rollouts

    hp = load_hyperparams("suite").with_values(n_envs=2, prefetch=False)
    venv = make_training_env("noise_bursts", hp, seed=0)
    lo, hi = env_config(**hp.env_kwargs).action.r_log10
    floor = 2.0 * (2.0 - lo) / (hi - lo) - 1.0
    labels = {}
    for name, given in (("plain", None), ("floored", {"noise_bursts": 2.0})):
        hp = hp.with_values(pretrain={"teacher_r_floor": given})
        labels[name] = np.concatenate(_privileged_rollouts(venv, hp, "noise_bursts", 400)[1])
    venv.close()
    assert labels["plain"][:, ACT_R].min() < floor - 0.1
    assert labels["floored"][:, ACT_R].min() >= floor - 1e-9
    np.testing.assert_array_equal(
        np.delete(labels["plain"], ACT_R, 1), np.delete(labels["floored"], ACT_R, 1)
    )


def _first_seed():
    """The first seed of the privileged rollouts' stream for environment 0 of 2."""
    from agents.evaluation.seeds import TRAIN_SEEDS
    from agents.training.imitation import seed_stream

    return seed_stream(0, 2, offset=TRAIN_SEEDS.stop // 2)


def test_the_cloning_term_pulls_the_actor_to_the_demonstrations():
    """``CloningTerm.step`` (behaviour cloning kept on during PPO) moves the actor's mean toward
    the demonstrated actions on the demonstrated states, and only the actor: the critic and the
    exploration noise are PPO's alone."""
    import torch

    from agents.training.imitation import CloningTerm, Demonstrations

    hp = load_hyperparams("nonstationary").with_values(
        n_envs=2,
        prefetch=False,
        pretrain=Pretrain(steps=1, epochs=1, bc_minibatches=200, bc_learning_rate=1e-3),
    )
    venv = make_training_env("nonstationary", hp, seed=0)
    model = make_ppo(venv, hp, seed=0)
    rng = np.random.default_rng(0)
    venv.reset()
    obs = []
    for _ in range(300):
        obs.append(venv.get_original_obs())
        venv.step(rng.uniform(-1, 1, (2, venv.action_space.shape[0])).astype(np.float32))
    states = np.concatenate(obs)
    # a demonstrator that acts on what it sees: the first observation's sign, on every action
    target = np.repeat(np.tanh(states[:, :1]), venv.action_space.shape[0], axis=1) * 0.8
    demos = Demonstrations(
        states.astype(np.float32), target.astype(np.float32), np.full(len(states), "nonstationary")
    )

    def gap() -> float:
        mean, _ = model.policy.predict(venv.normalize_obs(states), deterministic=True)
        return float(np.abs(mean - target).mean())

    critic = [p.detach().clone() for p in model.policy.value_net.parameters()]
    log_std = model.policy.log_std.detach().clone()
    before = gap()
    CloningTerm(model, venv, hp, demos, seed=0).step()
    assert gap() < 0.5 * before, (before, gap())
    for p, q in zip(model.policy.value_net.parameters(), critic, strict=True):
        assert torch.equal(p, q)
    assert torch.equal(model.policy.log_std, log_std)
    venv.close()


@pytest.mark.slow
def test_training_with_the_cloning_term_keeps_and_reads_back_its_demonstrations(tmp_path):
    """With ``pretrain.bc_minibatches`` a fresh run saves its demonstrations, the trained policy
    stays nearer them than the same run without the term, and a resumed run reads them back (a
    missing file is a one-line error naming it)."""
    import copy

    base = json.loads(HYPERPARAMS.read_text())
    hp = copy.deepcopy(base["scenarios"]["suite"])
    hp.update(eval_episodes=7, env_kwargs={**hp["env_kwargs"]})
    files = {}
    for name, minibatches in (("with", 100), ("without", 0)):
        spec = {
            **hp,
            "pretrain": {**hp["pretrain"], "bc_minibatches": minibatches, "bc_learning_rate": 3e-3},
        }
        files[name] = tmp_path / f"{name}.json"
        files[name].write_text(json.dumps({"version": 99, "scenarios": {"suite": spec}}))
    args = ["train", "--scenario", "suite", "--quick", "--timesteps", "1024", "--quiet"]
    gaps = {}
    for name in files:
        out = tmp_path / name
        assert main([*args, "--hyperparams", str(files[name]), "--out", str(out)]) == 0
        demos = np.load(tmp_path / "with" / "demonstrations.npz")
        last = out / "candidate.npz"  # the last validated policy, unless it was the best
        policy = NumpyPPOPolicy.load(last if last.exists() else out / "policy.npz")
        cloned = np.isin(demos["scenarios"], hp["pretrain"]["bc_scenarios"])  # the term's data
        obs, want = demos["obs"][cloned], np.clip(demos["actions"][cloned], -1, 1)
        actions = np.stack([policy.predict(o, deterministic=True)[0] for o in obs])
        gaps[name] = float(np.abs(actions - want).mean())
    assert not (tmp_path / "without" / "demonstrations.npz").exists()
    drawn = set(demos["scenarios"])  # suite flights: the scenarios drawn, several of them
    assert len(drawn) > 1 and drawn <= {*SUITE, "nonstationary_dense"}, drawn
    assert gaps["with"] < 0.5 * gaps["without"], gaps
    run = tmp_path / "with"
    assert main([*args, "--hyperparams", str(files["with"]), "--out", str(run)]) == 0
    (run / "demonstrations.npz").unlink()
    with pytest.raises(AeromagError, match=r"cannot read the demonstrations .*demonstrations\.npz"):
        train_ppo("suite", 256, 0, run, quick=True, progress=False, hyperparams=files["with"])


def test_the_cloning_term_keeps_only_the_scenarios_named():
    """``pretrain.bc_scenarios`` keeps the demonstrations flown in those scenarios (the others
    are PPO's alone); naming only scenarios never flown is a one-line error."""
    from agents.training.imitation import CloningTerm, Demonstrations

    hp = load_hyperparams("nonstationary").with_values(n_envs=2, prefetch=False)
    venv = make_training_env("nonstationary", hp, seed=0)
    model = make_ppo(venv, hp, seed=0)
    n_obs, n_act = venv.observation_space.shape[0], venv.action_space.shape[0]
    flown = np.array(["manoeuvre_heavy", "nonstationary_dense", "paper", "manoeuvre_heavy"])
    demos = Demonstrations(
        np.arange(4 * n_obs, dtype=np.float32).reshape(4, n_obs),
        np.zeros((4, n_act), np.float32),
        flown,
    )
    spec = Pretrain(steps=1, epochs=1, bc_minibatches=1, bc_scenarios=("manoeuvre_heavy", "paper"))
    hp = hp.with_values(pretrain=spec)
    kept = CloningTerm(model, venv, hp, demos, seed=0).demos
    np.testing.assert_array_equal(kept.obs, demos.obs[[0, 2, 3]])
    assert list(kept.scenarios) == ["manoeuvre_heavy", "paper", "manoeuvre_heavy"]
    hp = hp.with_values(pretrain={"bc_scenarios": ["degradation"]})
    with pytest.raises(AeromagError, match=r"bc_scenarios \['degradation'\]: no demonstration"):
        CloningTerm(model, venv, hp, demos, seed=0)
    venv.close()


@pytest.mark.parametrize("window", [10, 5])
def test_the_teacher_holds_a_step_for_the_same_time_at_any_decision_window(window):
    """The DAgger teacher (``teacher_after``) keeps T_p's Q at the top for the windows within
    30 samples after a step at K = 10 (3 windows) and K = 5 (6 windows): the same 3 s, so the
    student, which sees a step one window late, has as long to learn the response at K = 5."""
    from aeromag_env.environment.spaces import ACT_QP
    from agents.policies.baselines import PrivilegedPolicy
    from agents.training.imitation import TEACHER_AFTER_SAMPLES, teacher_after

    assert teacher_after(10) == 3 and teacher_after(5) == 6 and teacher_after(7) == 5
    env = gym.make(
        "AeroMag/Nonstationary-v0", **{**policy_env_kwargs("ppo"), "decision_window": window}
    )
    obs, _ = env.reset(seed=100_000)
    teacher = PrivilegedPolicy(env, after=teacher_after(window))
    step = int(env.unwrapped.episode.step_samples[0])
    raised, done = [], False
    while not done:
        k = env.unwrapped.filter.k
        action, _ = teacher.predict(obs)
        if action[ACT_QP] == 1.0 and k >= step:
            raised.append(k)
        obs, _, term, trunc, _ = env.step(action)
        done = term or trunc or k > step + 100
    held = raised[-1] + window - step  # samples after the step with T_p's Q at the top
    assert TEACHER_AFTER_SAMPLES <= held < TEACHER_AFTER_SAMPLES + window, held


def test_quick_is_one_preset_applied_after_every_default():
    """``--quick`` replaces the sizes of the hyperparameter file, whatever it says, and the
    commands' default sizes; a size the caller gives is kept."""
    from agents.training.ppo import TIMESTEPS
    from agents.training.quick import QUICK, quick_hyperparams, sized

    for scenario in ("nonstationary", "suite"):
        big = load_hyperparams(scenario).with_values(n_envs=64, n_steps=4096, eval_episodes=500)
        quick = quick_hyperparams(big)
        assert {k: getattr(quick, k) for k in QUICK.ppo} == dict(QUICK.ppo)
        assert quick.pretrain is not None
        assert {k: getattr(quick.pretrain, k) for k in QUICK.pretrain} == dict(QUICK.pretrain)
        assert quick.env_kwargs == big.env_kwargs and quick.gamma == big.gamma
    assert sized(None, TIMESTEPS, True, QUICK.train_timesteps) == QUICK.train_timesteps
    assert sized(None, TIMESTEPS, False, QUICK.train_timesteps) == TIMESTEPS
    assert sized(64, TIMESTEPS, True, QUICK.train_timesteps) == 64
