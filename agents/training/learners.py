"""The general tuner's learners, side by side: PPO and four more, trained on the same suite.

* ``ppo``: the shipped general policy's recipe (:func:`agents.training.ppo.train_ppo` with the
  ``suite`` entry of ``agents/training/hyperparams/ppo.json``: imitation of the privileged
  policy, then PPO).
* ``recurrent_ppo``: sb3-contrib's RecurrentPPO (an LSTM before the actor's layers), from scratch.
* ``sac`` (stable-baselines3) and ``tqc`` (sb3-contrib): off-policy, from scratch.
* ``cmaes``: a non-gradient baseline, CMA-ES (the ``cma`` package) over a linear rule
  ``a = tanh(W x̂ + b)`` on the normalised observation ``x̂``: every candidate of a generation
  flies the same training flights (simulated once), scored by its mean reward per step.

Hyperparameters live in ``agents/training/hyperparams/learners.json`` (the ``ppo`` learner reads
``ppo.json``), one model per learner (:mod:`agents.training.hyperparameters`); every learner
trains on ``suite`` flights from the training seeds, validates every ``eval_every``
environment steps on the same validation flights (split over the suite's scenarios) and keeps
the checkpoint with the best validation score (``select_by``: the worst scenario's mean RMSE
ratio to the tuned constant), exported for numpy
(:func:`agents.policies.policy_file.export_actor`; a recurrent export carries its LSTM). The
validation points, with environment steps and wall-clock seconds, are the learning curve
(``training.json``). torch, stable-baselines3, sb3-contrib and cma are imported here only
(extra ``rl``).
"""

from __future__ import annotations

import inspect
import json
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from aeromag_env.atomic import check_output_set, write_text
from aeromag_env.environment.ids import SUITE
from aeromag_env.errors import ConfigError, HyperparameterError
from agents.evaluation.seeds import TRAIN_SEEDS
from agents.policies.numpy_policy import NumpyPolicy
from agents.policies.policy_file import export_actor, write_policy
from agents.training import LEARNERS, SUITE_SCENARIO
from agents.training.hyperparams_file import read_learners
from agents.training.imitation import seed_stream
from agents.training.learner_hyperparameters import (
    CMAESHyperparams,
    LearnerHyperparams,
    SB3Hyperparams,
)
from agents.training.quick import quick_learner
from agents.training.validation import Validator

#: The learners' hyperparameter file (every learner but PPO, whose file is ``ppo.json``).
HYPERPARAMS = Path(__file__).with_name("hyperparams") / "learners.json"
#: The training scenario of the general tuner: each flight drawn from the suite.
SCENARIO = SUITE_SCENARIO
#: What every learner's ``training.json`` holds beside its curve.
OUTPUTS = ("policy.npz", "candidate.npz", "training.json")


def learner_hyperparams(learner: str, path: Path = HYPERPARAMS) -> LearnerHyperparams:
    """The hyperparameters of ``learner`` in ``path``: its entry under the file's ``common``
    settings, a model of
    :data:`~agents.training.learner_hyperparameters.LEARNER_MODELS` (every learner of the file
    checked); a one-line :class:`~aeromag_env.errors.HyperparameterError` naming the file and
    the field otherwise."""
    learners = read_learners(path)
    if learner not in learners:
        raise HyperparameterError(
            f"no hyperparameters for learner {learner!r} in {path}; available: "
            f"{', '.join(learners) or 'none'}"
        )
    return learners[learner]


def _algorithm(learner: str) -> Any:
    if learner == "recurrent_ppo":
        from sb3_contrib import RecurrentPPO

        return RecurrentPPO
    if learner == "tqc":
        from sb3_contrib import TQC

        return TQC
    if learner == "sac":
        from stable_baselines3 import SAC

        return SAC
    raise HyperparameterError(f"unknown learner {learner!r}; valid: {', '.join(LEARNERS)}")


def constructor_parameters(learner: str) -> dict[str, inspect.Parameter]:
    """The constructor parameters of ``learner``'s algorithm that a learner's ``algo`` may set
    (with their annotations and defaults)."""
    fixed = {"self", "policy", "env", "policy_kwargs", "verbose", "seed", "device"}
    params = inspect.signature(_algorithm(learner).__init__).parameters
    return {k: p for k, p in params.items() if k not in fixed and not k.startswith("_")}


def algorithm_name(learner: str) -> str:
    """The class name of ``learner``'s algorithm (``SAC``, ``TQC``, ``RecurrentPPO``)."""
    return str(_algorithm(learner).__name__)


def sb3_keywords(hp: SB3Hyperparams) -> dict[str, Any]:
    """The constructor keywords of ``hp``'s algorithm: the ``algo`` keys given (the others
    take the algorithm's defaults) and ``policy_kwargs``."""
    return {
        **hp.algo.model_dump(exclude_unset=True),
        "policy_kwargs": {
            k: list(v) if isinstance(v, tuple) else v
            for k, v in hp.policy_kwargs.model_dump(exclude_unset=True).items()
        },
    }


def train_learner(
    learner: str,
    seed: int,
    out: Path,
    timesteps: int | None = None,
    quick: bool = False,
    progress: bool = False,
    hyperparams: Path = HYPERPARAMS,
) -> dict[str, Any]:
    """Train ``learner`` (one of :data:`LEARNERS`) with training seed ``seed`` into ``out``:
    ``policy.npz`` (the best validated checkpoint), ``training.json`` (the summary and the
    learning curve). ``timesteps`` overrides the entry's; ``quick`` shrinks everything to a
    test's size (:data:`agents.training.quick.QUICK`). Returns the summary."""
    out = Path(out)
    if learner == "ppo":
        from agents.training.ppo import train_ppo

        return train_ppo(SCENARIO, timesteps, seed, out, quick=quick, progress=progress)
    if learner not in LEARNERS:
        raise HyperparameterError(f"unknown learner {learner!r}; valid: {', '.join(LEARNERS)}")
    check_output_set(out, OUTPUTS, [hyperparams])
    try:
        hp = learner_settings(learner, hyperparams, quick=quick, timesteps=timesteps)
    except ConfigError as e:  # a --timesteps the model refuses
        raise HyperparameterError(f"{hyperparams}: learners.{learner}.{e}") from None
    return run_learner(learner, hp, seed, out)


def learner_settings(
    learner: str,
    hyperparams: Path = HYPERPARAMS,
    *,
    quick: bool = False,
    timesteps: int | None = None,
) -> LearnerHyperparams:
    """What :func:`train_learner` trains ``learner`` with: its entry of ``hyperparams``
    (:func:`learner_hyperparams`), with the quick sizes for ``quick``
    (:func:`agents.training.quick.quick_learner`) and ``timesteps`` (when given) for the
    entry's."""
    hp = learner_hyperparams(learner, hyperparams)
    if quick:
        hp = quick_learner(hp)
    if timesteps is not None:
        hp = hp.with_values(timesteps=timesteps)
    return hp


def run_learner(
    learner: str,
    hp: LearnerHyperparams,
    seed: int,
    out: Path,
    on_validation: Callable[[dict[str, Any]], None] | None = None,
) -> dict[str, Any]:
    """Train ``learner`` (not ``ppo``) with the settings ``hp`` (of :func:`learner_settings`)
    into ``out`` and write ``training.json``; ``on_validation(point)`` is called after each
    validation point of the curve (:class:`Curve`). Returns the summary."""
    out.mkdir(parents=True, exist_ok=True)
    from agents.training.ppo import training_torch

    curve = Curve(out, learner, seed, hp, on_validation)
    t0 = time.perf_counter()
    with training_torch():
        if isinstance(hp, CMAESHyperparams):
            steps = _train_cmaes(hp, seed, curve)
        else:
            steps = _train_sb3(learner, hp, seed, curve)
    summary = {
        "learner": learner,
        "scenario": SCENARIO,
        "seed": seed,
        "timesteps": steps,
        "train_seconds_this_run": time.perf_counter() - t0,
        "best_validation_score": curve.best,
        "best_validation_rmse_nt": curve.best_rmse,
        "hyperparams": {**hp.to_entry(), "version": hp.version},
        "curve": curve.points,
    }
    write_text(out / "training.json", json.dumps(summary, indent=1))
    return summary


def selection_score(point: dict[str, Any]) -> float:
    """The score a validation point is selected by (lower is better): ``validation_score``
    (the entry's ``select_by``) when there is one, else the mean validation RMSE [nT]."""
    return float(point.get("validation_score", point["validation_rmse_nt"]))


class Curve:
    """Validation points of one run (environment steps, wall-clock seconds, the validator's
    scores) and the best candidate so far kept as ``policy.npz``; ``on_validation(point)``, when
    given, is called with each point once it is recorded (``aeromag tune`` reports it)."""

    def __init__(
        self,
        out: Path,
        learner: str,
        seed: int,
        hp: LearnerHyperparams,
        on_validation: Callable[[dict[str, Any]], None] | None = None,
    ) -> None:
        self.out, self.learner, self.seed, self.hp = out, learner, seed, hp
        self.on_validation = on_validation
        self.validator = Validator(hp.select_by, SCENARIO, hp.eval_episodes)
        self.points: list[dict[str, Any]] = []
        self.best, self.best_rmse = float("inf"), float("inf")
        self.t0 = time.perf_counter()
        self.validation_seconds = 0.0

    def meta(self, timesteps: int) -> dict[str, Any]:
        return {
            "scenario": SCENARIO,
            "env_kwargs": dict(self.hp.env_kwargs),
            "seed": self.seed,
            "timesteps": int(timesteps),
            "learner_hyperparams_version": self.hp.version,
        }

    def validate(self, timesteps: int, write: Callable[[Path, dict[str, Any]], Path]) -> None:
        """Export the current policy with ``write(path, meta)``, score it, keep it if best."""
        start = time.perf_counter()
        candidate = write(self.out / "candidate.npz", self.meta(timesteps))
        point = {"timesteps": int(timesteps), **self.validator(NumpyPolicy.load(candidate))}
        self.validation_seconds += time.perf_counter() - start
        point["seconds"] = time.perf_counter() - self.t0
        point["train_seconds"] = point["seconds"] - self.validation_seconds
        self.points.append(point)
        score = selection_score(point)
        if score < self.best:
            self.best, self.best_rmse = score, point["validation_rmse_nt"]
            candidate.replace(self.out / "policy.npz")
        if self.on_validation is not None:
            self.on_validation(point)


def _training_env(hp: LearnerHyperparams, seed: int) -> Any:
    """``n_envs`` batched training environments on the suite under ``VecNormalize``, each
    resetting from its own stream of training seeds (as
    :func:`agents.training.ppo.make_training_env`)."""
    from stable_baselines3.common.vec_env import VecNormalize

    from aeromag_env.environment.sb3 import AeroMagSB3VecEnv

    n = hp.n_envs
    streams = [seed_stream(rank, n, offset=1000 * seed) for rank in range(n)]
    venv = AeroMagSB3VecEnv(
        n,
        scenario=SCENARIO,
        reset_seeds=streams,
        prefetch=hp.prefetch,
        step_infos="episode_end",  # SB3's learners read infos at episode ends only
        **hp.env_kwargs,
    )
    gamma = getattr(hp.algo, "gamma", None)
    if gamma is None:  # the algorithm's default
        gamma = constructor_parameters(hp.learner)["gamma"].default
    return VecNormalize(
        venv, norm_obs=True, norm_reward=hp.normalize_reward, gamma=float(gamma), clip_obs=10.0
    )


def _train_sb3(learner: str, hp: SB3Hyperparams, seed: int, curve: Curve) -> int:
    from stable_baselines3.common.callbacks import BaseCallback

    from agents.training.ppo import _quiet

    venv = _training_env(hp, seed)
    policy = "MlpLstmPolicy" if learner == "recurrent_ppo" else "MlpPolicy"
    kwargs = sb3_keywords(hp)
    model = _quiet(_algorithm(learner)(policy, venv, seed=seed, device="cpu", verbose=0, **kwargs))

    def write(path: Path, meta: dict[str, Any]) -> Path:
        return export_actor(model, venv, path, meta)

    class Validate(BaseCallback):
        def _on_training_start(self) -> None:
            self.next = hp.eval_every
            curve.validate(0, write)

        def _on_step(self) -> bool:
            if self.model.num_timesteps >= self.next:
                self.next += hp.eval_every
                curve.validate(self.model.num_timesteps, write)
            return True

    model.learn(hp.timesteps, callback=Validate())
    if curve.points[-1]["timesteps"] != model.num_timesteps:
        curve.validate(model.num_timesteps, write)
    venv.close()
    return int(model.num_timesteps)


def _train_cmaes(hp: CMAESHyperparams, seed: int, curve: Curve) -> int:
    """CMA-ES over ``(W, b)`` of ``a = tanh(W x̂ + b)``: each generation's candidates fly the
    same ``flights`` training flights, as many of each scenario of the suite (one batched
    environment of popsize × flights, the flights simulated once); a candidate's loss is minus
    its mean reward per step over them.
    The normalisation of ``x̂`` is fixed first, from the zero rule's observations on
    ``normalisation_flights`` training flights (as ARS normalises, but frozen)."""
    import cma

    from aeromag_env.environment.vec_env import AeroMagCompensationVecEnv

    algo = hp.algo
    pop, n_flights = algo.popsize, algo.flights  # flights: a multiple of the suite's scenarios
    scenarios = [SUITE[j % len(SUITE)] for j in range(n_flights)]
    env = AeroMagCompensationVecEnv(
        pop * n_flights,
        scenario=SCENARIO,
        autoreset_mode="Disabled",
        flight_cache=max(n_flights, algo.normalisation_flights),
        **hp.env_kwargs,
    )
    n_obs = int(np.prod(env.single_observation_space.shape or ()))
    n_act = int(np.prod(env.single_action_space.shape or ()))
    seeds = seed_stream(0, 1, offset=TRAIN_SEEDS.start + 1000 * seed + 500)
    mean, var, steps = _statistics(env, [next(seeds) for _ in range(algo.normalisation_flights)])
    norm = {"obs_mean": mean, "obs_var": var, "obs_clip": np.array(10.0), "obs_eps": np.array(1e-8)}

    def arrays(theta: np.ndarray) -> dict[str, np.ndarray]:
        w = theta[: n_act * n_obs].reshape(n_act, n_obs)
        return {**norm, "w_out": w, "b_out": theta[n_act * n_obs :]}

    def write_for(theta: np.ndarray) -> Callable[[Path, dict[str, Any]], Path]:
        def write(path: Path, meta: dict[str, Any]) -> Path:
            meta = {**meta, "activation": "tanh", "head": "tanh", "learner": "CMA-ES"}
            return write_policy(arrays(theta), meta, path)

        return write

    es = cma.CMAEvolutionStrategy(
        np.zeros(n_act * (n_obs + 1)),
        algo.sigma0,
        {"popsize": pop, "seed": seed + 1, "verbose": -9},
    )
    scale = np.sqrt(var + 1e-8)
    curve.validate(steps, write_for(es.mean))
    next_eval = steps + hp.eval_every
    while steps < hp.timesteps:
        thetas = np.array(es.ask())
        flights = [next(seeds) for _ in range(n_flights)]
        loss, used = _generation(env, thetas, flights, scenarios, mean, scale, n_act, n_obs)
        es.tell(list(thetas), list(loss))
        steps += used
        if steps >= next_eval or steps >= hp.timesteps:
            next_eval += hp.eval_every
            curve.validate(steps, write_for(es.mean))
    env.close()
    return steps


def _statistics(env: Any, flights: list[int]) -> tuple[np.ndarray, np.ndarray, int]:
    """Mean and variance of the observations of the zero rule (action 0) on ``flights``."""
    seen: list[np.ndarray] = []
    steps = 0
    for start in range(0, len(flights), env.num_envs):
        chunk = flights[start : start + env.num_envs]
        seeds = (chunk * env.num_envs)[: env.num_envs]
        obs, _ = env.reset(seed=seeds)
        alive = np.zeros(env.num_envs, bool)
        alive[: len(chunk)] = True
        while alive.any():
            seen.append(obs[alive].astype(np.float64))
            obs, _, term, trunc, _ = env.step(np.zeros(env.action_space.shape, np.float32))
            steps += int(alive.sum())
            ended = term | trunc
            alive &= ~ended
            if ended.any():
                obs, _ = env.reset(seed=seeds, options={"reset_mask": ended})
    x = np.concatenate(seen)
    return x.mean(axis=0), x.var(axis=0), steps


def _generation(
    env: Any,
    thetas: np.ndarray,
    flights: list[int],
    scenarios: list[str],
    mean: np.ndarray,
    scale: np.ndarray,
    n_act: int,
    n_obs: int,
) -> tuple[np.ndarray, int]:
    """Each candidate's loss (minus its mean over ``flights`` of the mean reward per step) and
    the environment steps spent; environment ``c·F + j`` flies flight ``j`` (of scenario
    ``scenarios[j]``) for candidate ``c``."""
    pop, n_flights = len(thetas), len(flights)
    w = thetas[:, : n_act * n_obs].reshape(pop, n_act, n_obs)
    b = thetas[:, n_act * n_obs :]
    obs = _reset(env, flights, scenarios, np.ones(env.num_envs, bool))
    total = np.zeros(pop * n_flights)
    count = np.zeros(pop * n_flights)
    alive = np.ones(pop * n_flights, bool)
    while alive.any():
        x = np.clip((obs - mean) / scale, -10.0, 10.0).reshape(pop, n_flights, n_obs)
        act = np.tanh(np.einsum("cao,cfo->cfa", w, x) + b[:, None, :])
        obs, reward, term, trunc, _ = env.step(act.reshape(pop * n_flights, n_act))
        total += np.where(alive, reward, 0.0)
        count += alive
        ended = term | trunc
        alive &= ~ended
        if ended.any():  # fly the same (cached) flight again until every candidate is done
            obs = _reset(env, flights, scenarios, ended)
    per_flight = (total / np.maximum(count, 1)).reshape(pop, n_flights)
    return -per_flight.mean(axis=1), int(count.sum())


def _reset(env: Any, flights: list[int], scenarios: list[str], mask: np.ndarray) -> np.ndarray:
    """Reset the environments of ``mask``: environment ``i`` to flight ``flights[i % F]`` of
    scenario ``scenarios[i % F]``; the observations of every environment."""
    which = np.arange(env.num_envs) % len(flights)
    seeds = [flights[i] for i in which]
    obs = None
    for scenario in dict.fromkeys(scenarios):
        picked = mask & np.array([scenarios[i] == scenario for i in which])
        if picked.any():
            obs, _ = env.reset(seed=seeds, options={"reset_mask": picked, "scenario": scenario})
    assert obs is not None
    return obs
