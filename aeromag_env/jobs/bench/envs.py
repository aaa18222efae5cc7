"""Environment and training speed for ``aeromag bench``.

* ``env_single_steps_per_s`` — ``AeroMagCompensation-v0`` steps per second, one env, K = 10,
  zero actions, one ``nominal`` episode (steps only: the flight is simulated in ``reset``),
  against ``env_numpy_reference_steps_per_s``: the plain-numpy reference filter's samples per
  second divided by K (an env stepping that filter).
* ``env_batched_steps_per_s`` — environment steps per second of the vector environment with
  :data:`VEC_ENVS` environments, the same protocol (seeds 100 000 + i, steps only).
* ``env_reset_s`` — seconds per reset of one env (simulating a ``nominal`` flight): the part
  of training that batching does not speed up.
* ``ppo_batched_steps_per_s``, ``ppo_dummyvec_steps_per_s`` — stable-baselines3 PPO ``learn``
  throughput (environment steps per second, resets and updates included) with the training
  environments of ``aeromag train`` (``agents/training/hyperparams/ppo.json``, scenario
  ``nonstationary``: its 8 envs, n_steps, batch size, epochs, network; torch set up as in training,
  :func:`agents.training.ppo.training_torch`): batched with flights prefetched in a worker process
  (the default), SB3's ``DummyVecEnv``, and ``ppo_batched_no_prefetch_steps_per_s`` (batched
  stepping alone). The four run side by side in one process, taking turns one rollout (and its
  update) at a time, the order rotating each turn, so that the slow drifts of a shared machine's
  speed fall on all of them alike (run one after another, single repeats of the share below
  scattered from −6 to 59 %). Steady-state throughput: one untimed rollout first (the first reset of
  every environment, torch's first calls), then ``learn`` goes on, timed, for five episodes per
  environment in each repeat (with 8; two with 64), the resets at episode ends included. A training
  run of 1.5M steps has 20–160 episodes per environment, so its first reset (``env_reset_s`` per
  environment) weighs little. With them the share of each run's time spent in the environments
  (``ppo_*_env_time_share``) and the microseconds per environment step in each part of the run
  (``ppo_*_{env,forward,update,rest}_us_per_step``: the environments' ``step_wait``, the policy's
  forward pass in the rollouts, the updates, the rest — rollout buffer, normalisation, SB3's loop);
  ``ppo_free_*``: PPO on :func:`free_vec_env`, PPO's own cost alone; ``ppo_batched_ratio_min`` /
  ``_max``: the range over the repeats of the batched variant's ratio to ``DummyVecEnv`` in the same
  repeat. ``ppo64_*``: the same with 64 environments.
* ``ppo_env_share`` — the environment's share of PPO's wall time with the batched training
  environments, ``1 − batched / free`` (steps per second with prefetching against the
  zero-cost environment of the same spaces, episode length in steps and PPO settings), from
  the two runs of each repeat, median over the repeats (5 in a full run), with its range
  ``ppo_env_share_min`` / ``_max``; ``ppo64_env_share``: the same with 64 environments, whose
  target is at most 20 % (with 8, PPO's own work leaves the environments 17–22 µs per step:
  the 15 % once asked there is out of reach, and the share with 8 is printed without a
  target). It is wall time on a shared machine: the prefetching worker simulates flights on
  the other core, and what another process takes of the cores is taken from the variants
  unequally (the spread of the repeats says how much). It counts all the time the environment
  costs PPO, torch's too (the policy's forward pass runs slower after an environment step than
  after the zero-cost one's). The flights are simulated afresh, none is replayed (a training
  run never flies a flight twice).
* ``ppo_env_to_filter_ratio`` — the environments' cost inside PPO against the bare compiled
  filter's cost of the same samples, both per environment step, median over the repeats:
  ``ppo_env_us_per_step`` (= ``ppo_batched_env_us_per_step``: the batched + prefetch run's
  time in the environments' ``step_wait`` — the compiled step, the Python around it, the
  resets) over ``ppo_filter_us_per_step``: the compiled batched filter alone
  (:func:`aeromag_env.compensation.kalman_batch.advance_batch` with its arrays packed once,
  the kernel the environments' step runs inside) advancing the flights of the first reset of
  the same training environments (the same number, scenario and seeds) by one decision window
  of K = ``ppo_decision_window`` samples each, call after call; a flight that reaches its end
  is restored to its start, untimed. Only the calls are timed: no action mapping, scoring,
  observation or reset, and Q and R stay the scenario's (no action scales them). It takes its
  turn among the PPO variants (:func:`_interleaved`), as many environment steps per turn as a
  rollout, so the two are measured over the same minutes (unlike ``K /
  filter_compiled_samples_per_s``: one flight filtered alone, back to back, away from PPO's
  rollouts, which may read lower on a busy machine). The target is at most 1.5× with 8
  environments; ``ppo_env_to_filter_ratio_min`` / ``_max``: the range of the ratio within a
  repeat; ``ppo64_*``: the same with 64 environments (both on the cores' threads,
  :mod:`aeromag_env.threads`).
* ``ppo_env_to_filter_in_ppo_ratio`` — a diagnostic beside it, no target: the same
  environments' cost over ``ppo_filter_in_ppo_us_per_step``, the same bare filter on the same
  flights stepped inside PPO as the environments are (:data:`IN_PPO`: PPO learning on the
  zero-cost environment whose ``step_wait`` advances every flight by one decision window, only
  those calls timed), so that the policy's forward pass, the rollout buffer and the updates
  run between its calls as they run between the environments' steps. What the environments
  cost beyond it is their own work (the action, the score, the observation, the Python around
  the step, the resets); what the filter costs there beyond the back-to-back figure is what
  running inside PPO costs any kernel.
"""

from __future__ import annotations

import copy
import functools
import statistics
import time
from collections.abc import Callable
from typing import Any

import gymnasium as gym
import numpy as np

from aeromag_env.compensation.arrays import CORE_ARRAYS, filter_arrays, packed
from aeromag_env.compensation.kalman_batch import BatchFilterState, advance_batch
from aeromag_env.compensation.kalman_reference import run_reference
from aeromag_env.compensation.kernel_layout import INTS
from aeromag_env.compensation.model import FilterConfig
from aeromag_env.environment.ids import register_all
from aeromag_env.environment.spaces import BASE_ACTIONS

register_all()  # the environment ids gym.make reads (a second call does nothing)

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

#: The run that steps the bare filter inside PPO (:func:`bench_ppo`): a diagnostic beside the
#: speed target's bare filter, which runs in a turn of its own, back to back.
IN_PPO = "filter_in_ppo"

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
    the batched variant's ratio to ``DummyVecEnv`` in the same repeat; the environment's
    share ``1 − batched / free`` of each repeat, its median and range; and the environments'
    cost per step against the bare compiled filter's (:class:`BareFilter`, taking its turn
    with them) and against the same filter stepped inside PPO (:data:`IN_PPO`, a turn of its
    own). Figures are named ``{prefix}_{variant}_…``, ``{prefix}_env_share…``,
    ``{prefix}_{env,filter,filter_in_ppo}_us_per_step`` and ``{prefix}_env_to_filter_ratio…``,
    ``{prefix}_env_to_filter_in_ppo_ratio…``. ``timesteps``
    must be a multiple of the number of environments (the filter then advances as many
    environment steps)."""
    from agents.training import ppo

    hp = ppo.load_hyperparams("nonstationary")
    hp = hp.with_values(n_envs=n_envs or hp.n_envs, **sizes)
    if timesteps <= 0 or timesteps % hp.n_envs:
        raise ValueError(f"timesteps must be a multiple of n_envs ({hp.n_envs}), got {timesteps}")
    free, bare = _stand_ins(
        ppo.make_training_env("nonstationary", hp.with_values(prefetch=False), 0)
    )
    inside = bare.fresh()  # the same flights, advanced inside PPO's own rollouts
    with ppo.training_torch():
        models: dict[str, Any] = {}
        running = {name: {part: [0.0] for part in PARTS} for name in PPO_VARIANTS}
        running["filter"] = {"kernel": bare.seconds}
        for name, overrides in PPO_VARIANTS.items():
            if overrides is None:
                venv = ppo.normalized(free(), hp)
            else:
                venv = ppo.make_training_env("nonstationary", hp.with_values(**overrides), seed=0)
            model = models[name] = ppo.make_ppo(venv, hp, seed=0)
            inner, totals = venv.venv, running[name]
            inner.step_wait = timed(inner.step_wait, totals["env"])
            model.policy.forward = timed(model.policy.forward, totals["forward"])
            model.train = timed(model.train, totals["update"])
        # the bare filter as the environments run: in the zero-cost env's step_wait, one
        # decision window of every flight per step, PPO's rollouts and updates around it
        situ = free(functools.partial(inside, hp.n_envs))
        models[IN_PPO] = ppo.make_ppo(ppo.normalized(situ, hp), hp, seed=0)
        running[IN_PPO] = {"kernel": inside.seconds}
        time.sleep(2.0)  # a prefetching worker starts up (in training: once per run)
        rollout = hp.n_steps * hp.n_envs
        for model in models.values():
            model.learn(rollout)  # the first reset, torch warmed up
        bare(rollout)  # the compiled kernel loaded
        runs: dict[str, Callable[[int], object]] = {
            name: functools.partial(model.learn, reset_num_timesteps=False)  # no reset: goes on
            for name, model in models.items()
        }
        try:
            seconds, parts = _interleaved(
                runs | {"filter": bare}, running, timesteps, repeats, rollout
            )
        finally:
            for model in models.values():
                model.get_env().close()
    figures = _ppo_figures(prefix, timesteps, seconds, parts)
    figures |= {f"{prefix}_n_envs": hp.n_envs, f"{prefix}_timesteps": timesteps}
    return figures | filter_figures(prefix, parts, timesteps, bare.window)


def _ppo_figures(
    prefix: str, timesteps: int, seconds: dict[str, list[float]], parts: Seconds
) -> dict[str, Any]:
    """:func:`bench_ppo`'s figures of the PPO variants from each repeat's ``seconds`` and its
    ``parts``: steps per second, time shares and parts per step, the batched variant's ratio
    to ``DummyVecEnv`` and the environments' share of PPO's time."""
    rates = {name: [timesteps / s for s in seconds[name]] for name in PPO_VARIANTS}
    figures: dict[str, Any] = {}
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


def filter_figures(prefix: str, parts: Seconds, timesteps: int, window: int) -> dict[str, Any]:
    """The batched + prefetch environments' and the bare filter's µs per environment step
    (medians over the repeats), the quotient of the two medians and the range of the quotient
    within a repeat; ``parts``: the seconds of :func:`_interleaved` (``batched``'s ``env``,
    ``filter``'s ``kernel``: one entry per repeat of ``timesteps`` environment steps). The same
    against the filter stepped inside PPO (:data:`IN_PPO`'s ``kernel``) when it ran:
    ``{prefix}_filter_in_ppo_us_per_step``, ``{prefix}_env_to_filter_in_ppo_ratio…``."""
    env = [1e6 * s / timesteps for s in parts["batched"]["env"]]
    figures: dict[str, Any] = {f"{prefix}_decision_window": window}
    for name in ("filter", IN_PPO):
        if name not in parts:  # older bench.json files have no IN_PPO part
            continue
        kernel = [1e6 * s / timesteps for s in parts[name]["kernel"]]
        paired = [e / k for e, k in zip(env, kernel, strict=True)]
        env_us, filter_us = statistics.median(env), statistics.median(kernel)
        figures |= {
            f"{prefix}_env_us_per_step": env_us,
            f"{prefix}_{name}_us_per_step": filter_us,
            f"{prefix}_env_to_{name}_ratio": env_us / filter_us,
            f"{prefix}_env_to_{name}_ratio_min": min(paired),
            f"{prefix}_env_to_{name}_ratio_max": max(paired),
        }
    return figures


def _interleaved(
    runs: dict[str, Callable[[int], object]],
    running: Seconds,
    timesteps: int,
    repeats: int,
    rollout: int,
) -> tuple[dict[str, list[float]], Seconds]:
    """Each repeat, every run goes on for ``timesteps`` environment steps (``runs[name](steps)``:
    a model ``learn``-ing on, the bare filter), one rollout (and its update) at a time, the runs
    taking turns and the order rotating each turn. Returns the seconds each run spent in each
    repeat, and of them the seconds in each of its parts (``running[name][part][0]``, which
    the timed methods add to). Taking turns a rollout at a time (about half a second) pairs the
    variants against the minutes-long drifts of a shared machine's speed, which a whole run of
    one variant after another took unequally."""
    names = list(runs)
    seconds: dict[str, list[float]] = {name: [] for name in names}
    parts: Seconds = {name: {part: [] for part in running[name]} for name in names}
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
                runs[name](steps)
                spent[name] += time.perf_counter() - t0
        for name in names:
            seconds[name].append(spent[name])
            for part, total in running[name].items():
                parts[name][part].append(total[0])
    return seconds, parts


def _stand_ins(venv: Any) -> tuple[Callable[..., Any], BareFilter]:
    """The training environments ``venv`` (batched, under ``VecNormalize``; reset here, then
    closed) stood in for: a factory of :func:`free_vec_env` (its optional argument the
    ``work`` of each step) with their spaces, number of environments and episode length (in
    steps: the longest flight over the decision window), and the bare filter on the flights of
    their first reset."""
    venv.reset()
    batched = venv.venv.venv
    n_envs, window = venv.num_envs, int(batched.config.decision_window)
    steps = -(-int(batched.episode_lengths.max()) // window)
    spaces = (venv.observation_space, venv.action_space)
    bare = BareFilter(batched.filters, window)
    venv.close()
    return lambda work=None: free_vec_env(n_envs, *spaces, steps, work), bare


class BareFilter:
    """The compiled batched filter alone, stepping flights as the environments step them.

    Each call ``bare(steps)`` advances every flight by one decision window of K samples
    (:func:`aeromag_env.compensation.kalman_batch.advance_batch`, its arrays packed once) per
    ``N`` environment steps, ``steps // N`` calls in all, and adds the calls' wall time to
    ``seconds[0]``; a flight that reaches its end (as an episode ends) is restored to its
    start between calls, untimed. Nothing else an environment step does is done: no action
    scales Q or R, no score, no observation.

    Parameters
    ----------
    filters : the N flights' filters at their start (copied: they are not advanced)
    window : K, samples per decision window

    Attributes
    ----------
    seconds : one-element list: the kernel calls' wall time so far [s] (the caller may zero it)
    filters : the flights being advanced (a copy of ``filters``)
    """

    def __init__(self, filters: BatchFilterState, window: int) -> None:
        self.window = int(window)
        self.seconds = [0.0]
        self._fresh = filters
        self.filters = copy.deepcopy(filters)
        self._arrays = packed(filter_arrays(self.filters))

    def fresh(self) -> BareFilter:
        """Another bare filter on the same flights, from their start, with its own clock."""
        return BareFilter(self._fresh, self.window)

    def __call__(self, steps: int) -> None:
        f = self.filters
        k = f.ints[:, INTS.k]
        for _ in range(steps // f.num_flights):
            k0 = k.copy()
            k1 = np.minimum(k0 + self.window, f.n)
            t0 = time.perf_counter()
            advance_batch(f.mode, k0, k1, self._arrays)
            self.seconds[0] += time.perf_counter() - t0
            for i in np.flatnonzero(k1 >= f.n):
                self._restart(int(i))

    def _restart(self, i: int) -> None:
        """Flight i back at its start."""
        for name in CORE_ARRAYS:
            getattr(self.filters, name)[i] = getattr(self._fresh, name)[i]


def free_vec_env(
    n_envs: int,
    observation_space: Any,
    action_space: Any,
    episode_steps: int,
    work: Callable[[], object] | None = None,
) -> Any:
    """An SB3 ``VecEnv`` that costs nothing: a fixed observation, zero reward, every episode
    ``episode_steps`` long and ended as a time limit (with the info entries SB3 reads). PPO
    trained on it measures its own cost per step: the ceiling of any environment's speed-up.
    With ``work``, each ``step_wait`` calls it first (the bare filter stepped inside PPO)."""
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
            if work is not None:
                work()
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


def timed(fn: Callable[..., Any], total: list[float]) -> Callable[..., Any]:
    """``fn`` that adds its wall time to ``total[0]``."""

    def wrapper(*args: Any, **kwargs: Any) -> Any:
        t0 = time.perf_counter()
        try:
            return fn(*args, **kwargs)
        finally:
            total[0] += time.perf_counter() - t0

    return wrapper
