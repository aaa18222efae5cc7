import gymnasium as gym
import numpy as np
import pytest
from gymnasium.error import ResetNeeded
from gymnasium.vector import AutoresetMode

import aeromag_env  # noqa: F401  (registers the environment)
from aeromag_env.environment.observations import NAMES
from aeromag_env.environment.vec_env import AeroMagCompensationVecEnv
from tests._helpers import observations


def _assert_identical(a, b, path="result"):
    """Same structure, dtypes and values (NaN equal to NaN)."""
    if isinstance(a, dict):
        assert a.keys() == b.keys(), f"{path}: keys differ: {sorted(a.keys() ^ b.keys())}"
        for key in a:
            _assert_identical(a[key], b[key], f"{path}[{key!r}]")
    elif isinstance(a, tuple | list) or (isinstance(a, np.ndarray) and a.dtype == object):
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            _assert_identical(x, y, f"{path}[{i}]")
    elif a is None:
        assert b is None, path
    else:
        assert np.asarray(a).dtype == np.asarray(b).dtype, path
        np.testing.assert_array_equal(a, b, err_msg=path)


def _pair(n, mode, **kw):
    ours = gym.make_vec(
        "AeroMagCompensation-v0",
        num_envs=n,
        vectorization_mode="vector_entry_point",
        autoreset_mode=mode,
        **kw,
    )
    sync = gym.make_vec(
        "AeroMagCompensation-v0",
        num_envs=n,
        vectorization_mode="sync",
        vector_kwargs={"autoreset_mode": mode},
        **kw,
    )
    return ours, sync


@pytest.mark.parametrize(
    "mode, split_q",
    [
        (AutoresetMode.NEXT_STEP, False),
        (AutoresetMode.SAME_STEP, False),
        (AutoresetMode.NEXT_STEP, True),
    ],
)
def test_equals_gymnasium_sync_vector_env_of_single_envs(mode, split_q):
    """Over two autoresets (30-step flights), random actions beyond the clip range; with a T_p
    action (split_q) also every optional observation."""
    layout = {"observations": observations()}
    if split_q:
        layout = {"observations": NAMES, "action": {"permanent": "graded"}}
    ours, sync = _pair(3, mode, scenario="misspecified", duration_s=30.0, **layout)
    _assert_identical(ours.reset(seed=100_000), sync.reset(seed=100_000))
    rng = np.random.default_rng(0)
    ends = 0
    for _ in range(70):
        actions = rng.uniform(-1.5, 1.5, (3, 2 + split_q)).astype(np.float32)
        step = ours.step(actions)
        _assert_identical(step, sync.step(actions))
        ends += int(np.any(step[2] | step[3]))
    assert ends == 2


def test_flights_of_different_lengths_end_on_their_own():
    """A partial reset switches one environment to a longer scenario (12 000 vs 5 272 samples)."""
    ours, sync = _pair(2, AutoresetMode.NEXT_STEP, scenario="nominal", action={"mode": "absolute"})
    for env in (ours, sync):
        env.reset(seed=[100_000, 100_001])
    switch = {"scenario": "nonstationary", "reset_mask": np.array([False, True])}
    _assert_identical(
        ours.reset(seed=[None, 7], options=dict(switch)),
        sync.reset(seed=[None, 7], options=dict(switch)),
    )
    assert list(ours.unwrapped.episode_lengths) == [5272, 12000]
    actions = np.full((2, 2), 0.25, np.float32)
    for k in range(529):  # 528 steps end the shorter flight, the next one restarts it
        result = ours.step(actions)
        _assert_identical(result, sync.step(actions))
        assert result[3][0] == (k == 527) and not result[3][1]
    info = result[4]
    assert info["_flight_seed"][0] and not info["_sample"][0] and info["sample"][1] == 5290


def test_make_vec_builds_it_and_it_follows_the_vector_api():
    env = gym.make_vec(
        "AeroMagCompensation-v0",
        num_envs=4,
        duration_s=20.0,
        observations=observations(),
        vectorization_mode="vector_entry_point",
    )
    assert isinstance(env, AeroMagCompensationVecEnv) and env.spec.id == "AeroMagCompensation-v0"
    assert env.metadata["autoreset_mode"] == AutoresetMode.NEXT_STEP
    assert env.single_observation_space.shape == (7,) and env.observation_space.shape == (4, 7)
    assert env.action_space.shape == (4, 2) and env.action_space.dtype == np.float32
    obs, info = env.reset(seed=1)
    assert obs.dtype == np.float32 and obs in env.observation_space
    assert info["flight_seed"].shape == (4,) and info["_flight_seed"].all()
    env.action_space.seed(0)
    obs, rewards, terminated, truncated, info = env.step(env.action_space.sample())
    assert obs in env.observation_space and rewards.dtype == np.float64
    assert rewards.shape == terminated.shape == truncated.shape == (4,)
    assert terminated.dtype == truncated.dtype == np.bool_
    assert set(info) >= {"rmse_window_nt", "_rmse_window_nt", "ror", "sample", "flight_seed"}


def test_bad_actions_and_calls_are_one_line_errors():
    env = AeroMagCompensationVecEnv(2, duration_s=20.0)
    with pytest.raises(ResetNeeded, match="reset"):
        env.step(np.zeros((2, 2)))
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"shape \(2, 2\).*got shape \(2,\)"):
        env.step(np.zeros(2))
    with pytest.raises(ValueError, match=r"shape \(2, 2\).*got shape \(3, 2\)"):
        env.step(np.zeros((3, 2), np.float32))  # the compiled step checks the shape
    with pytest.raises(ValueError, match=r"finite; environment 1 got \[nan, 0.0\]"):
        env.step(np.array([[0.0, 0.0], [np.nan, 0.0]]))
    with pytest.raises(ValueError, match=r"finite; environment 0 got \[inf, 0.0\]"):
        env.step(np.array([[np.inf, 0.0], [0.0, 0.0]], np.float32))
    with pytest.raises(ValueError, match="numbers"):
        env.step([["a", "b"], ["c", "d"]])
    with pytest.raises(ValueError, match="one seed per environment"):
        env.reset(seed=[1, 2, 3])
    with pytest.raises(ValueError, match="num_envs"):
        AeroMagCompensationVecEnv(0)


def test_actions_of_every_real_type_step_alike():
    """float32, float64, big-endian, strided and integer actions of the same values give the
    same step (the first two go to the compiled step as they are, the others converted)."""
    a = np.array([[0.5, -0.25], [1.0, 0.0]])
    kinds = [
        a,
        a.astype(np.float32),
        a.astype(">f8"),
        np.repeat(a, 2, axis=1)[:, ::2],
        np.array([[1, 0], [-1, 0]]),
    ]
    for given in kinds:
        env = AeroMagCompensationVecEnv(2, duration_s=20.0)
        env.reset(seed=3)
        obs, rewards, *_ = env.step(given)
        ref = AeroMagCompensationVecEnv(2, duration_s=20.0)
        ref.reset(seed=3)
        expected, expected_rewards, *_ = ref.step(given.astype(np.float64))
        np.testing.assert_array_equal(obs, expected)
        np.testing.assert_array_equal(rewards, expected_rewards)


def test_disabled_autoreset_refuses_to_step_an_ended_environment():
    env = AeroMagCompensationVecEnv(2, duration_s=5.0, autoreset_mode="Disabled")
    env.reset(seed=0)
    done = np.zeros(2, bool)
    while not done.any():
        _, _, terminated, truncated, _ = env.step(np.zeros((2, 2)))
        done = terminated | truncated
    with pytest.raises(ResetNeeded, match=r"environments \[0, 1\] ended"):
        env.step(np.zeros((2, 2)))
    obs, info = env.reset(options={"reset_mask": done})
    assert not obs.any() and info["_flight_seed"].all()
    env.step(np.zeros((2, 2)))


def test_building_either_environment_loads_no_training_or_plotting_package():
    """``gym.make`` and ``gym.make_vec`` of the environment import neither torch,
    stable-baselines3 nor matplotlib (the stable-baselines3 adapter is imported by its users)."""
    import subprocess
    import sys

    code = (
        "import sys, gymnasium as gym, aeromag_env;"
        "gym.make('AeroMagCompensation-v0');"
        "gym.make_vec('AeroMagCompensation-v0', num_envs=2,"
        " vectorization_mode='vector_entry_point');"
        "print(' '.join(sorted(m for m in sys.modules"
        " if m.split('.')[0] in ('torch', 'stable_baselines3', 'matplotlib'))))"
    )
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert run.stdout.strip() == ""


def test_many_environments_on_threads_equal_single_envs_and_refuse_before_moving():
    """17 environments (the step spread over threads: more than one chunk) with every optional
    observation, a step limit and random actions: bitwise the single environments. A
    non-finite action, or stepping an ended environment with autoreset disabled, is refused
    before any environment moves."""
    n = 17
    kw = {"preset": "general", "scenario": "misspecified", "duration_s": 30.0}
    ours, sync = _pair(n, AutoresetMode.NEXT_STEP, max_episode_steps=20, **kw)
    _assert_identical(ours.reset(seed=5), sync.reset(seed=5))
    rng = np.random.default_rng(1)
    for _ in range(45):  # two episodes cut at 20 steps, and their restarts
        actions = rng.uniform(-1.5, 1.5, (n, 3)).astype(np.float32)
        _assert_identical(ours.step(actions), sync.step(actions))
    k = ours.unwrapped.filters.k
    bad = rng.uniform(-1, 1, (n, 3))
    bad[13, 2] = np.inf
    with pytest.raises(ValueError, match=r"finite; environment 13 got \[.*inf\]"):
        ours.step(bad)
    np.testing.assert_array_equal(ours.unwrapped.filters.k, k)  # nothing moved

    disabled = AeroMagCompensationVecEnv(n, autoreset_mode="Disabled", max_episode_steps=2, **kw)
    disabled.reset(seed=0)
    disabled.step(np.zeros((n, 3)))
    _, _, _, truncated, _ = disabled.step(np.zeros((n, 3)))
    assert truncated.all()
    k = disabled.filters.k
    with pytest.raises(ResetNeeded, match="ended"):
        disabled.step(np.zeros((n, 3)))
    np.testing.assert_array_equal(disabled.filters.k, k)
