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
  (batched stepping alone); the variants alternate within each repeat; runs long enough for
  five episodes per environment, so that the first reset weighs as little as in a real
  training run. With them the share of each run's time spent in the environments
  (``ppo_*_env_time_share``): the rest — policy inference, rollout buffer, gradient updates —
  is the same for all. ``ppo64_*``: the same
  with 64 environments (two episodes each).
"""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable
from typing import Any

import gymnasium as gym
import numpy as np

import aeromag_env  # noqa: F401  (registers the environment)
from aeromag_env.kalman_model import FilterConfig
from aeromag_env.kalman_reference import run_reference

#: Environments of the batched-environment figure.
VEC_ENVS = 64
#: First evaluation seed (the same flights as the single-env figure).
SEED = 100_000


def _episode_rate(env: Any, num_envs: int) -> float:
    """Env steps per second over one episode of every environment (steps only, no reset)."""
    env.reset(seed=SEED)
    action = np.zeros((num_envs, 2) if num_envs > 1 else 2, np.float32)
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
    batched = gym.make_vec("AeroMagCompensation-v0", num_envs=VEC_ENVS, scenario="nominal",
                           vectorization_mode="vector_entry_point")  # fmt: skip
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


#: PPO variants: name → hyperparameter overrides (the rest as ``aeromag train``).
PPO_VARIANTS: dict[str, dict[str, Any]] = {
    "dummyvec": {"vec_env": "dummy"},
    "batched": {"vec_env": "batched", "prefetch": True},
    "batched_no_prefetch": {"vec_env": "batched", "prefetch": False},
}


def bench_ppo(timesteps: int, repeats: int, n_envs: int | None = None,
              prefix: str = "ppo") -> dict[str, Any]:  # fmt: skip
    """PPO ``learn(timesteps)`` steps per second for each of :data:`PPO_VARIANTS`, with
    ``ppo.json``'s hyperparameters (``n_envs`` overridden if given), alternating within each
    repeat; and the share of each run's time spent inside the environments' ``step_wait``
    (stepping, and the resets done there). Figures are named ``{prefix}_{variant}_…``."""
    from agents.ppo import load_hyperparams, make_ppo, make_training_env, training_torch

    hp = load_hyperparams("nonstationary")
    hp = {**hp, "n_envs": n_envs or int(hp["n_envs"])}
    rates: dict[str, list[float]] = {name: [] for name in PPO_VARIANTS}
    shares: dict[str, list[float]] = {name: [] for name in PPO_VARIANTS}
    with training_torch():
        for _ in range(repeats):
            for name, overrides in PPO_VARIANTS.items():
                venv = make_training_env("nonstationary", {**hp, **overrides}, seed=0)
                inner, in_env = venv.venv, [0.0]
                inner.step_wait = _timed(inner.step_wait, in_env)
                model = make_ppo(venv, hp, seed=0)
                time.sleep(2.0)  # a prefetching worker starts up (in training: once per run)
                t0 = time.perf_counter()
                model.learn(timesteps)
                seconds = time.perf_counter() - t0
                rates[name].append(timesteps / seconds)
                shares[name].append(in_env[0] / seconds)
                venv.close()
    figures: dict[str, Any] = {f"{prefix}_n_envs": hp["n_envs"], f"{prefix}_timesteps": timesteps}
    for name in PPO_VARIANTS:
        figures[f"{prefix}_{name}_steps_per_s"] = statistics.median(rates[name])
        figures[f"{prefix}_{name}_env_time_share"] = statistics.median(shares[name])
    return figures


def _timed(fn: Callable[[], Any], total: list[float]) -> Callable[[], Any]:
    """``fn`` that adds its wall time to ``total[0]``."""

    def wrapper() -> Any:
        t0 = time.perf_counter()
        try:
            return fn()
        finally:
            total[0] += time.perf_counter() - t0

    return wrapper
