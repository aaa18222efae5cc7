import gymnasium as gym
import numpy as np
import pytest
import torch

import aeromag_env  # noqa: F401  (registers the environment)
from aeromag_env.environment.sb3 import AeroMagSB3VecEnv
from aeromag_env.errors import AeromagError
from agents.training.ppo import load_hyperparams, make_training_env
from tests._helpers import observations

ENV_KWARGS = {  # 25-step flights
    "observations": observations(),
    "action": {"mode": "absolute"},
    "duration_s": 25.0,
}


def _hp(kind, **kw):
    base = load_hyperparams("nonstationary").with_values(n_envs=3, env_kwargs=ENV_KWARGS)
    return base.with_values(vec_env=kind, **kw)


@pytest.mark.parametrize("step_infos", ["every", "episode_end"])
def test_training_env_rollouts_equal_dummy_vec_env(step_infos):
    """Same training seeds, same actions → the same normalised observations, rewards, dones and
    infos (terminal observations, truncation flags) as DummyVecEnv over single envs; with
    ``episode_end`` (training's) the infos of the environments that ended, empty dicts else."""
    ours = make_training_env("nonstationary", _hp("batched"), seed=0)
    assert isinstance(ours.venv, AeroMagSB3VecEnv)
    assert not ours.venv._every_info  # training builds infos at episode ends only
    ours.venv._every_info = step_infos == "every"
    dummy = make_training_env("nonstationary", _hp("dummy"), seed=0)
    np.testing.assert_array_equal(ours.reset(), dummy.reset())
    assert ours.venv.reset_infos == dummy.venv.reset_infos
    rng = np.random.default_rng(1)
    ends = 0
    for _ in range(60):
        actions = rng.uniform(-1, 1, (3, 2)).astype(np.float32)
        (o1, r1, d1, i1), (o2, r2, d2, i2) = ours.step(actions), dummy.step(actions)
        np.testing.assert_array_equal(o1, o2)
        np.testing.assert_array_equal(r1, r2)
        np.testing.assert_array_equal(d1, d2)
        for a, b, done in zip(i1, i2, d1, strict=True):
            if step_infos == "episode_end" and not done:
                assert a == {}
                continue
            assert a.keys() == b.keys()
            for key in a:
                np.testing.assert_array_equal(a[key], b[key], err_msg=key)
        ends += int(d1.any())
    assert ends == 2 and ours.venv.reset_infos == dummy.venv.reset_infos


def test_step_infos_other_than_the_two_is_refused():
    with pytest.raises(ValueError, match="step_infos must be one of"):
        AeroMagSB3VecEnv(1, duration_s=5.0, step_infos="never")


def test_tiny_ppo_trains_identically_with_either_vectorisation():
    from stable_baselines3 import PPO

    torch.set_num_threads(1)
    params = []
    for kind in ("batched", "dummy"):
        venv = make_training_env("nonstationary", _hp(kind, n_envs=2), seed=0)
        model = PPO(
            "MlpPolicy",
            venv,
            n_steps=32,
            batch_size=32,
            n_epochs=2,
            seed=0,
            device="cpu",
            policy_kwargs={"net_arch": [16]},
        )
        model.learn(128)
        params.append([p.detach().numpy().copy() for p in model.policy.parameters()])
    for a, b in zip(*params, strict=True):
        np.testing.assert_array_equal(a, b)


def test_seed_then_reset_seeds_each_environment_like_a_single_env():
    venv = AeroMagSB3VecEnv(2, duration_s=5.0)
    venv.seed(3)
    obs = venv.reset()
    single = gym.make("AeroMagCompensation-v0", duration_s=5.0)
    seeds = [single.reset(seed=s)[1]["flight_seed"] for s in (3, 4)]
    assert [info["flight_seed"] for info in venv.reset_infos] == seeds
    assert obs.shape == (2, 2) and venv.env_is_wrapped(gym.Wrapper) == [False, False]
    assert venv.get_attr("render_mode") == [None, None]


def test_unknown_vectorisation_is_a_one_line_error():
    with pytest.raises(AeromagError, match="vec_env must be batched or dummy"):
        make_training_env("nonstationary", _hp("subproc"), seed=0)
