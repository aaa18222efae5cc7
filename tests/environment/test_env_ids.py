"""One registered Gymnasium id per scenario (``AeroMag/Nonstationary-v0``…), with
``gym.make``, ``gym.make_vec`` and stable-baselines3, ``max_episode_steps`` and ``render_mode``
passed through, and the episode's totals in the final info when a TimeLimit ends it.

The independent truths: Gymnasium's own ``TimeLimit``, ``RecordEpisodeStatistics`` and ``sync``
vector environment over single environments, and SB3's ``make_vec_env``.
"""

from __future__ import annotations

from dataclasses import replace

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode

import aeromag_env
from aeromag_env.environment.config import PRESETS
from aeromag_env.environment.ids import SCENARIOS, TRAINING_SCENARIOS, env_id
from aeromag_env.environment.vec_env import AeroMagCompensationVecEnv
from tests._helpers import observations
from tests.environment.test_vec_env import _assert_identical

#: Totals the final info of an episode carries (the single env's and the vector env's).
TOTALS = ("episode_rmse_nt", "divergences", "outliers_rejected")


def test_every_scenario_has_an_id_that_makes_it():
    assert env_id("calibration_then_survey") == "AeroMag/CalibrationThenSurvey-v0"
    ids = [env_id(s) for s in SCENARIOS + TRAINING_SCENARIOS]
    assert len(set(ids)) == len(ids) == 10 and all(i in gym.registry for i in ids)
    assert aeromag_env.ENV_ID in gym.registry
    for scenario in SCENARIOS + TRAINING_SCENARIOS:
        env = gym.make(env_id(scenario), duration_s=20.0)
        assert env.unwrapped.config.scenario == scenario and env.spec.id == env_id(scenario)
    with pytest.raises(KeyError, match="unknown scenario 'bogus'; valid: paper, nominal"):
        env_id("bogus")


def test_registering_twice_changes_nothing():
    before = {i: gym.spec(i) for i in gym.registry if i.startswith("AeroMag")}
    aeromag_env.environment.ids.register_all()
    assert {i: gym.spec(i) for i in gym.registry if i.startswith("AeroMag")} == before


def test_a_time_limit_ends_the_episode_with_its_totals():
    """``gym.make(..., max_episode_steps=7)``: the 7th step is truncated by Gymnasium's
    TimeLimit and its info carries the episode's RMSE (before ``score_from``: over the part
    flown), divergences and rejected outliers, as every step's does (the environment cannot
    know where a wrapper will cut); ``RecordEpisodeStatistics`` adds its own."""
    env = gym.wrappers.RecordEpisodeStatistics(gym.make("AeroMag/Nominal-v0", max_episode_steps=7))
    env.reset(seed=100_000)
    for k in range(7):
        _, _, terminated, truncated, info = env.step(np.zeros(2, np.float32))
        assert truncated == (k == 6) and not terminated
        assert all(key in info for key in TOTALS)
    assert info["episode"]["l"] == 7 and np.isfinite(info["episode_rmse_nt"])
    # the same first 7 steps without the limit: the RMSE over the 70 samples flown
    free = gym.make("AeroMag/Nominal-v0")
    free.reset(seed=100_000)
    for _ in range(7):
        free.step(np.zeros(2, np.float32))
    errors = free.unwrapped.episode.truth_interf[:70] - free.unwrapped.filter.est[:70]
    assert info["episode_rmse_nt"] == pytest.approx(np.sqrt(np.mean(errors**2)), rel=1e-12)


@pytest.mark.parametrize("mode", [AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP])
def test_the_vector_env_truncates_alike(mode):
    """``gym.make_vec(id, max_episode_steps=5)``: bitwise the sync vector env of
    ``gym.make(id, max_episode_steps=5)`` over three or four episodes, totals in the final infos."""
    kw = {"num_envs": 3, "duration_s": 30.0, "max_episode_steps": 5}
    ours = gym.make_vec(
        "AeroMag/Misspecified-v0",
        vectorization_mode="vector_entry_point",
        autoreset_mode=mode,
        **kw,
    )
    sync = gym.make_vec(
        "AeroMag/Misspecified-v0",
        vectorization_mode="sync",
        vector_kwargs={"autoreset_mode": mode},
        **kw,
    )
    assert isinstance(ours, AeroMagCompensationVecEnv) and ours.max_episode_steps == 5
    _assert_identical(ours.reset(seed=100_000), sync.reset(seed=100_000))
    rng, cuts = np.random.default_rng(0), 0
    for _ in range(22):
        actions = rng.uniform(-1.5, 1.5, (3, 2)).astype(np.float32)
        step = ours.step(actions)
        _assert_identical(step, sync.step(actions))
        if step[3].any():
            cuts += 1
            infos = step[4]["final_info"] if mode == AutoresetMode.SAME_STEP else step[4]
            assert all(infos[f"_{key}"].all() for key in TOTALS)
    assert cuts == (4 if mode == AutoresetMode.SAME_STEP else 3)  # NEXT_STEP: a reset step


def test_bad_limits_are_refused_in_one_line():
    for bad in (0, -1, 2.5, "5", True):
        with pytest.raises(ValueError, match="max_episode_steps must be an integer ≥ 1 or None"):
            AeroMagCompensationVecEnv(2, duration_s=20.0, max_episode_steps=bad)


def test_render_mode_passes_through_gym_make():
    pytest.importorskip("matplotlib")
    env = gym.make("AeroMag/Nominal-v0", render_mode="rgb_array", duration_s=20.0)
    env.reset(seed=1)
    env.step(np.zeros(2, np.float32))
    frame = env.render()
    assert frame.ndim == 3 and frame.shape[2] == 3 and frame.dtype == np.uint8


def test_stable_baselines3_makes_it_by_id():
    pytest.importorskip("stable_baselines3")
    from stable_baselines3.common.env_checker import check_env
    from stable_baselines3.common.env_util import make_vec_env

    check_env(gym.make("AeroMag/Nonstationary-v0", duration_s=20.0).unwrapped)
    vec = make_vec_env(
        "AeroMag/Nonstationary-v0",
        n_envs=2,
        seed=100_000,
        env_kwargs={"duration_s": 20.0, "observations": observations()},
    )
    obs = vec.reset()
    assert obs.shape == (2, 7)
    _, _, dones, infos = vec.step(np.zeros((2, 2), np.float32))
    assert not dones.any() and infos[0]["sample"] == 10


def test_the_shipped_policy_makes_its_own_environment():
    """The kwargs travel with the policy: ``make_env`` builds the id of its training scenario
    with its env_kwargs, and a whole (short) episode runs; the bare id is refused with the way
    out in the message, not a broadcast error."""
    from agents.policies.numpy_policy import NumpyPPOPolicy
    from tests._helpers import SHIPPED

    policy = NumpyPPOPolicy.load(SHIPPED["policy"])
    env = policy.make_env(duration_s=60.0, max_episode_steps=40)
    assert env.spec.id == "AeroMag/Nonstationary-v0" and env.spec.max_episode_steps == 40
    obs, _ = env.reset(seed=100_000)
    done, steps = False, 0
    while not done:
        obs, _, terminated, truncated, info = env.step(policy.predict(obs)[0])
        done, steps = terminated or truncated, steps + 1
    assert steps == 40 and np.isfinite(info["episode_rmse_nt"])
    bare, _ = gym.make("AeroMag/Nonstationary-v0").reset(seed=1)
    with pytest.raises(ValueError, match=r"policy\.make_env\(\), or pass it policy\.env_kwargs"):
        policy.predict(bare)


def test_a_scenario_given_twice_is_refused_in_one_line():
    from aeromag_env.environment.env import EnvConfig
    from aeromag_env.errors import ConfigError

    for config in ({"scenario": "nominal"}, EnvConfig(scenario="paper")):
        with pytest.raises(ConfigError, match="scenario given twice: 'nonstationary' by the id"):
            gym.make("AeroMag/Nonstationary-v0", config=config)
    agree = gym.make(
        "AeroMag/Nonstationary-v0", config={"scenario": "nonstationary", "preset": "general"}
    )
    assert agree.unwrapped.config == replace(PRESETS["general"], scenario="nonstationary")
    named = gym.make("AeroMag/Nonstationary-v0", config={"preset": "general"})
    assert named.unwrapped.config == agree.unwrapped.config
    assert gym.make("AeroMagCompensation-v0", config={"scenario": "paper"}).unwrapped.scenario == (
        "paper"
    )


def test_the_vector_env_renders_each_environment_as_the_single_env_does():
    """``gym.make_vec(id, render_mode="rgb_array")``: one frame per environment, the single env's
    panels for the same flight and actions (against samples); SB3 tiles them; None without."""
    pytest.importorskip("matplotlib")
    from aeromag_env.environment.render import render_panels

    vec = gym.make_vec(
        "AeroMag/Nominal-v0",
        num_envs=2,
        vectorization_mode="vector_entry_point",
        render_mode="rgb_array",
        duration_s=20.0,
    )
    single = gym.make("AeroMag/Nominal-v0", duration_s=20.0).unwrapped
    vec.reset(seed=5)
    single.reset(seed=6)  # environment 1 of the vector env is seeded 5 + 1
    actions = np.array([[0.5, -0.5], [1.0, 0.25]], np.float32)
    for _ in range(3):
        vec.step(actions)
        single.step(actions[1])
    frames = vec.render()
    assert len(frames) == 2 and all(f.dtype == np.uint8 and f.ndim == 3 for f in frames)
    k, f = single.filter.k, single.filter
    err = single.episode.truth_interf[:k] - f.est[:k]
    expected = render_panels(
        "nominal", np.arange(k), "sample", err, f.ror[:k], f.qoq[:k], f.q_scale[:k], f.r_scale[:k]
    )
    np.testing.assert_array_equal(frames[1], expected)
    assert not np.array_equal(frames[0], frames[1])
    quiet = gym.make_vec(
        "AeroMag/Nominal-v0", num_envs=2, vectorization_mode="vector_entry_point", duration_s=20.0
    )
    quiet.reset(seed=5)
    assert quiet.render() is None
    with pytest.raises(ValueError, match="render_mode must be None or 'rgb_array'"):
        gym.make_vec(
            "AeroMag/Nominal-v0",
            num_envs=2,
            vectorization_mode="vector_entry_point",
            render_mode="human",
        )


def test_stable_baselines3_tiles_the_frames():
    pytest.importorskip("stable_baselines3")
    pytest.importorskip("matplotlib")
    from aeromag_env.environment.sb3 import AeroMagSB3VecEnv

    venv = AeroMagSB3VecEnv(2, render_mode="rgb_array", duration_s=5.0)
    venv.reset()
    venv.step(np.zeros((2, 2), np.float32))
    frames = venv.get_images()
    tiled = venv.render()
    assert venv.render_mode == "rgb_array" and len(frames) == 2
    assert tiled.shape[2] == 3 and tiled.size >= 2 * frames[0].size
