"""Environment and training speed for ``aeromag bench``.

* ``env_single_steps_per_s`` — ``AeroMagCompensation-v0`` steps per second, one env, K = 10,
  zero actions, one ``nominal`` episode (steps only: the flight is simulated in ``reset``),
  against ``env_numpy_reference_steps_per_s``: the plain-numpy reference filter's samples per
  second divided by K (an env stepping that filter).
* ``env_batched_steps_per_s`` — environment steps per second of the vector environment with
  :data:`VEC_ENVS` environments, the same protocol (seeds 100 000 + i, steps only).
* ``env_reset_s`` — seconds per reset of one env (simulating a ``nominal`` flight): the part
  of training that batching does not speed up.
* ``ppo_batched_steps_per_s``, ``ppo_dummyvec_steps_per_s`` — stable-baselines3 PPO
  ``learn`` throughput (environment steps per second, resets and updates included) with the
  training environments of ``aeromag train`` (``agents/hyperparams/ppo.json``, scenario
  ``nonstationary``: its 8 envs, n_steps, batch size, epochs, network; torch set up as in
  training, :func:`agents.ppo.training_torch`): batched with flights prefetched in a worker
  process (the default), SB3's ``DummyVecEnv``, and ``ppo_batched_no_prefetch_steps_per_s``
  (batched stepping alone). The four run side by side in one process, taking turns one
  rollout (and its update) at a time, the order rotating each turn, so that the slow drifts of
  a shared machine's speed fall on all of them alike (until 2026-11-27 each repeat ran one
  variant's whole run after another's, and single repeats of the share below scattered from
  −6 to 59 %). Steady-state throughput: one untimed rollout first (the first reset of every
  environment, torch's first calls), then ``learn`` goes on, timed, for five episodes per
  environment in each repeat (with 8; two with 64), the resets at episode ends included. A
  training run of 1.5M steps has 20–160 episodes per environment, so its first reset
  (``env_reset_s`` per environment) weighs little. With them the share of each run's time
  spent in the environments (``ppo_*_env_time_share``) and the microseconds per environment
  step in each part of the run (``ppo_*_{env,forward,update,rest}_us_per_step``: the
  environments' ``step_wait``, the policy's forward pass in the rollouts, the updates, the
  rest — rollout buffer, normalisation, SB3's loop); ``ppo_free_*``: PPO on
  :func:`free_vec_env`, PPO's own cost alone; ``ppo_batched_ratio_min`` / ``_max``: the range
  over the repeats of the batched variant's ratio to ``DummyVecEnv`` in the same repeat.
  ``ppo64_*``: the same with 64 environments.
* ``ppo_env_share`` — the environment's share of PPO's wall time with the batched training
  environments, ``1 − batched / free`` (steps per second with prefetching against the
  zero-cost environment of the same spaces, episode length in steps and PPO settings), from
  the two runs of each repeat, median over the repeats (5 with 8 environments in a full run),
  with its range ``ppo_env_share_min`` / ``_max``; the target is at most 15 % with 8
  environments. It is wall time on a shared machine: the prefetching worker simulates flights
  on the other core, and what another process takes of the cores is taken from the variants
  unequally (the spread of the repeats says how much). It counts all the time the
  environment costs PPO, torch's too (the policy's forward pass runs slower after an
  environment step than after the zero-cost one's). The flights are simulated afresh, none is
  replayed (a training run never flies a flight twice).
"""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable
from typing import Any

import gymnasium as gym
import numpy as np

import aeromag_env  # noqa: F401  (registers the environment)
from aeromag_env.compensation.kalman_reference import run_reference
from aeromag_env.compensation.model import FilterConfig
from aeromag_env.environment.spaces import BASE_ACTIONS

#: Environments of the batched-environment figure.
VEC_ENVS = 64
#: First evaluation seed (the same flights as the single-env figure).
SEED = 100_000


def _episode_rate(env: Any, num_envs: int) -> float:
    """Env steps per second over one episode of every environment (steps only, no reset)."""
    env.reset(seed=SEED)
    size = len(BASE_ACTIONS)  # zero a_q, a_r: the constant policy
    action = np.zeros((num_envs, size) if num_envs > 1 else size, np.float32)
    done = np.zeros(num_envs, bool)
    t0, steps = time.perf_counter(), 0
    while not done.all():
        _, _, terminated, truncated, _ = env.step(action)
        done |= np.asarray(terminated | truncated)
        steps += num_envs
    return steps / (time.perf_counter() - t0)


def bench_env(repeats: int) -> dict[str, float]:
    """One env and the vector env, K = 10, ``nominal``; the numpy-filter env as reference."""
    single = gym.make("AeroMagCompensation-v0", scenario="nominal")
    batched = gym.make_vec(
        "AeroMagCompensation-v0",
        num_envs=VEC_ENVS,
        scenario="nominal",
        vectorization_mode="vector_entry_point",
    )
    _episode_rate(single, 1)  # warm: numba cache load, first-step checks
    _episode_rate(batched, VEC_ENVS)
    single_rates, batched_rates, resets = [], [], []
    for _ in range(repeats):
        single_rates.append(_episode_rate(single, 1))
        batched_rates.append(_episode_rate(batched, VEC_ENVS))
        t0 = time.perf_counter()
        single.reset(seed=SEED)
        resets.append(time.perf_counter() - t0)
    ep = single.unwrapped.episode  # type: ignore[attr-defined]
    n = 1000
    t_ref = []
    for _ in range(min(repeats, 3)):
        t0 = time.perf_counter()
        run_reference(FilterConfig(), ep.y[:n], ep.t_b[:n], ep.tdot_b[:n])
        t_ref.append(time.perf_counter() - t0)
    return {
        "env_single_steps_per_s": statistics.median(single_rates),
        "env_numpy_reference_steps_per_s": n / statistics.median(t_ref) / 10,
        "env_batched_steps_per_s": statistics.median(batched_rates),
        "env_reset_s": statistics.median(resets),
    }


#: Seconds per PPO variant and part of its time: one entry per repeat.
Seconds = dict[str, dict[str, list[float]]]
#: The parts of a PPO run's time timed apart: the environments' ``step_wait`` (stepping and the
#: resets done there), the policy's forward pass in the rollouts, the updates (``train``).
PARTS = ("env", "forward", "update")

#: PPO variants: name → hyperparameter overrides (the rest as ``aeromag train``); ``free``: the
#: zero-cost stand-in environment (:func:`free_vec_env`), PPO's own cost alone.
PPO_VARIANTS: dict[str, dict[str, Any] | None] = {
    "dummyvec": {"vec_env": "dummy"},
    "batched": {"vec_env": "batched", "prefetch": True},
    "batched_no_prefetch": {"vec_env": "batched", "prefetch": False},
    "free": None,
}


def bench_ppo(
    timesteps: int,
    repeats: int,
    n_envs: int | None = None,
    prefix: str = "ppo",
    **sizes: int,
) -> dict[str, Any]:
    """PPO ``learn(timesteps)`` steps per second for each of :data:`PPO_VARIANTS`, with
    ``ppo.json``'s hyperparameters (``n_envs`` and the ``sizes`` — ``n_steps``, ``batch_size``
    — overridden if given), interleaved one rollout at
    a time (:func:`_interleaved`); the share of each run's time spent inside the environments'
    ``step_wait`` (stepping, and the resets done there); each variant's microseconds per
    environment step in each of :data:`PARTS` and in the rest; the range over the repeats of
    the batched variant's ratio to ``DummyVecEnv`` in the same repeat; and the environment's
    share ``1 − batched / free`` of each repeat, its median and range. Figures are named
    ``{prefix}_{variant}_…`` and ``{prefix}_env_share…``."""
    from agents import ppo

    hp = ppo.load_hyperparams("nonstationary")
    hp = hp.with_values(n_envs=n_envs or hp.n_envs, **sizes)
    free = _free_env_like(ppo.make_training_env("nonstationary", hp.with_values(prefetch=False), 0))
    with ppo.training_torch():
        models: dict[str, Any] = {}
        running = {name: {part: [0.0] for part in PARTS} for name in PPO_VARIANTS}
        for name, overrides in PPO_VARIANTS.items():
            if overrides is None:
                venv = ppo.normalized(free(), hp)
            else:
                venv = ppo.make_training_env("nonstationary", hp.with_values(**overrides), seed=0)
            model = models[name] = ppo.make_ppo(venv, hp, seed=0)
            inner, totals = venv.venv, running[name]
            inner.step_wait = _timed(inner.step_wait, totals["env"])
            model.policy.forward = _timed(model.policy.forward, totals["forward"])
            model.train = _timed(model.train, totals["update"])
        time.sleep(2.0)  # a prefetching worker starts up (in training: once per run)
        rollout = hp.n_steps * hp.n_envs
        for model in models.values():
            model.learn(rollout)  # the first reset, torch warmed up
        try:
            seconds, parts = _interleaved(models, running, timesteps, repeats, rollout)
        finally:
            for model in models.values():
                model.get_env().close()
    rates = {name: [timesteps / s for s in seconds[name]] for name in PPO_VARIANTS}
    figures: dict[str, Any] = {f"{prefix}_n_envs": hp.n_envs, f"{prefix}_timesteps": timesteps}
    for name in PPO_VARIANTS:
        total, part = seconds[name], parts[name]
        shares = [e / s for e, s in zip(part["env"], total, strict=True)]
        figures[f"{prefix}_{name}_steps_per_s"] = statistics.median(rates[name])
        figures[f"{prefix}_{name}_env_time_share"] = statistics.median(shares)
        rest = [t - sum(p) for t, *p in zip(total, *part.values(), strict=True)]
        for key, values in (*part.items(), ("rest", rest)):
            us = 1e6 * statistics.median(values) / timesteps
            figures[f"{prefix}_{name}_{key}_us_per_step"] = us
    paired = [b / d for b, d in zip(rates["batched"], rates["dummyvec"], strict=True)]
    figures[f"{prefix}_batched_ratio_min"] = min(paired)
    figures[f"{prefix}_batched_ratio_max"] = max(paired)
    env = [1.0 - b / f for b, f in zip(rates["batched"], rates["free"], strict=True)]
    figures[f"{prefix}_env_share"] = statistics.median(env)
    figures[f"{prefix}_env_share_min"] = min(env)
    figures[f"{prefix}_env_share_max"] = max(env)
    return figures


def _interleaved(
    models: dict[str, Any], running: Seconds, timesteps: int, repeats: int, rollout: int
) -> tuple[dict[str, list[float]], Seconds]:
    """Each repeat, every model goes on ``learn``-ing for ``timesteps`` steps, one rollout (and
    its update) at a time, the models taking turns and the order rotating each turn. Returns
    the seconds each model spent in each repeat, and of them the seconds in each part
    (``running[name][part][0]``, which the timed methods add to). Taking turns a rollout at a
    time (about half a second) pairs the variants against the minutes-long drifts of a shared
    machine's speed, which a whole run of one variant after another took unequally."""
    names = list(models)
    seconds: dict[str, list[float]] = {name: [] for name in names}
    parts: Seconds = {name: {part: [] for part in PARTS} for name in names}
    turns = max(1, -(-timesteps // rollout))
    for _ in range(repeats):
        spent = dict.fromkeys(names, 0.0)
        for totals in running.values():
            for total in totals.values():
                total[0] = 0.0
        for turn in range(turns):
            steps = min(rollout, timesteps - turn * rollout)
            for j in range(len(names)):
                name = names[(turn + j) % len(names)]
                t0 = time.perf_counter()
                models[name].learn(steps, reset_num_timesteps=False)  # no reset: goes on
                spent[name] += time.perf_counter() - t0
        for name in names:
            seconds[name].append(spent[name])
            for part in PARTS:
                parts[name][part].append(running[name][part][0])
    return seconds, parts


def _free_env_like(venv: Any) -> Callable[[], Any]:
    """A factory of :func:`free_vec_env` with the spaces, number of environments and episode
    length (in steps: the longest flight over the decision window) of the training environments
    ``venv`` (batched, under ``VecNormalize``; closed)."""
    venv.reset()
    batched = venv.venv.venv
    n_envs, window = venv.num_envs, int(batched.config.decision_window)
    steps = -(-int(batched.episode_lengths.max()) // window)
    spaces = (venv.observation_space, venv.action_space)
    venv.close()
    return lambda: free_vec_env(n_envs, *spaces, steps)


def free_vec_env(n_envs: int, observation_space: Any, action_space: Any, episode_steps: int) -> Any:
    """An SB3 ``VecEnv`` that costs nothing: a fixed observation, zero reward, every episode
    ``episode_steps`` long and ended as a time limit (with the info entries SB3 reads). PPO
    trained on it measures its own cost per step: the ceiling of any environment's speed-up."""
    from stable_baselines3.common.vec_env import VecEnv

    obs = np.clip(
        np.random.default_rng(0).standard_normal((n_envs, *observation_space.shape)),
        observation_space.low,
        observation_space.high,
    ).astype(np.float32)

    class FreeVecEnv(VecEnv):
        def __init__(self) -> None:
            super().__init__(n_envs, observation_space, action_space)
            self.steps = 0

        def reset(self) -> np.ndarray:
            self.steps = 0
            return obs.copy()

        def step_async(self, actions: np.ndarray) -> None:
            pass

        def step_wait(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[dict]]:
            self.steps += 1
            end = self.steps % episode_steps == 0
            infos: list[dict] = [{"TimeLimit.truncated": end} for _ in range(n_envs)]
            if end:
                for i, info in enumerate(infos):
                    info["terminal_observation"] = obs[i].copy()
            return obs.copy(), np.zeros(n_envs, np.float32), np.full(n_envs, end), infos

        def close(self) -> None:
            pass

        def get_attr(self, attr_name: str, indices: Any = None) -> list[Any]:
            return [None] * len(list(self._get_indices(indices)))

        def set_attr(self, attr_name: str, value: Any, indices: Any = None) -> None:
            pass

        def env_method(
            self, method_name: str, *args: Any, indices: Any = None, **kwargs: Any
        ) -> list[Any]:
            return [None] * len(list(self._get_indices(indices)))

        def env_is_wrapped(self, wrapper_class: Any, indices: Any = None) -> list[bool]:
            return [False] * len(list(self._get_indices(indices)))

    return FreeVecEnv()


def _timed(fn: Callable[..., Any], total: list[float]) -> Callable[..., Any]:
    """``fn`` that adds its wall time to ``total[0]``."""

    def wrapper(*args: Any, **kwargs: Any) -> Any:
        t0 = time.perf_counter()
        try:
            return fn(*args, **kwargs)
        finally:
            total[0] += time.perf_counter() - t0

    return wrapper
