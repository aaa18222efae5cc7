"""Train a stable-baselines3 PPO tuner (``aeromag train``) and export it for numpy inference.

Hyperparameters live in ``agents/training/hyperparams/ppo.json`` (versioned, RL Zoo style: one entry
per scenario, with the environment keyword arguments the policy is trained with), apart from the
environment's own configuration; in Python they are a
:class:`~agents.training.hyperparameters.PPOHyperparams`, which holds the defaults. Training resets
every environment with seeds from the training range only (``[0, 50 000)``); validation uses
``[50 000, 100 000)``; tests use ``≥ 100 000``. The training environments are stepped together
by the batched environment (:mod:`aeromag_env.environment.sb3`), or by SB3's ``DummyVecEnv``
with ``"vec_env": "dummy"``. Checkpoints (model + observation normalisation) are written
periodically and training resumes from the latest one. torch and stable-baselines3 are
imported here only (extra ``rl``).
"""

from __future__ import annotations

import contextlib
import json
import math
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from aeromag_env.atomic import check_output_set, output_set, write_text
from aeromag_env.environment.ids import register_all
from aeromag_env.environment.scenarios import check_scenario
from aeromag_env.errors import AeromagError, HyperparameterError
from agents.policies.numpy_policy import NumpyPPOPolicy
from agents.policies.policy_file import export_policy
from agents.training.hyperparameters import SB3_PPO_KEYS, PPOHyperparams
from agents.training.hyperparams_file import read_ppo
from agents.training.imitation import CloningTerm, Demonstrations, behaviour_clone, seed_stream
from agents.training.quick import QUICK, quick_hyperparams, sized
from agents.training.validation import Validator, validation_rmse

register_all()  # the environment ids gym.make reads (a second call does nothing)

HYPERPARAMS = Path(__file__).with_name("hyperparams") / "ppo.json"
#: The checkpoint, written as a set (the model, the observation normaliser, the curve).
CHECKPOINT = ("checkpoint.zip", "vecnormalize.pkl", "curve.json")
#: The other outputs in ``--out``: the best policy, the latest candidate, the summary, and the
#: demonstrations the cloning term keeps PPO near (``pretrain.bc_minibatches``; read on resume).
OUTPUTS = ("policy.npz", "candidate.npz", "training.json", "demonstrations.npz")
#: Environment steps of a training run by default (the shipped policies').
TIMESTEPS = 3_000_000


def load_hyperparams(scenario: str, path: Path = HYPERPARAMS) -> PPOHyperparams:
    """The hyperparameters of ``scenario`` from the file ``path``, checked
    (:mod:`agents.training.hyperparams_file`); a one-line HyperparameterError for a bad file or an
    absent scenario."""
    table = read_ppo(path)
    if scenario not in table.scenarios:
        available = ", ".join(table.scenarios) or "none"
        raise HyperparameterError(
            f"no PPO hyperparameters for {scenario!r} in {path}; available: {available}"
        )
    hp: PPOHyperparams = table.scenarios[scenario]
    return hp


class TrainingSeeds(gym.Wrapper):
    """Reset with the next seed of a fixed sequence from the training range (disjoint from
    validation and test seeds by construction)."""

    def __init__(self, env: gym.Env, seeds: Iterator[int]) -> None:
        super().__init__(env)
        self._seeds = seeds

    def reset(self, *, seed: int | None = None, options: dict | None = None) -> Any:
        return self.env.reset(seed=next(self._seeds), options=options)


#: How the training environments are vectorised: one batched environment stepping all of them
#: in one compiled call (default), or stable-baselines3's DummyVecEnv over single environments
#: (for comparison: same observations, rewards and seeds, hence the same training).
VEC_ENVS = ("batched", "dummy")


def make_training_env(scenario: str, hp: PPOHyperparams, seed: int) -> Any:
    """``n_envs`` training environments under ``VecNormalize``; ``hp.vec_env`` (one of
    :data:`VEC_ENVS`) chooses the vectorisation, ``hp.prefetch`` whether the batched one
    simulates flights ahead in a worker process. Environment ``rank`` resets with the seeds of
    ``seed_stream(rank, …)`` either way. ``hp.train_scenario`` trains on another scenario than
    the one validated and evaluated (e.g. ``nonstationary_dense``: the same flights with more
    interference steps)."""
    from stable_baselines3.common.vec_env import DummyVecEnv

    n_envs, kind = hp.n_envs, hp.vec_env
    scenario = check_scenario(hp.train_scenario or scenario)
    if kind not in VEC_ENVS:
        raise AeromagError(f"vec_env must be one of {', '.join(VEC_ENVS)}; got {kind!r}")
    streams = [seed_stream(rank, n_envs, offset=1000 * seed) for rank in range(n_envs)]
    if kind == "batched":
        from aeromag_env.environment.sb3 import AeroMagSB3VecEnv

        venv: Any = AeroMagSB3VecEnv(
            n_envs,
            scenario=scenario,
            reset_seeds=streams,
            prefetch=hp.prefetch,
            step_infos="episode_end",  # PPO reads infos at episode ends only
            **hp.env_kwargs,
        )
    else:

        def factory(rank: int) -> Any:
            def make() -> gym.Env:
                env = gym.make("AeroMagCompensation-v0", scenario=scenario, **hp.env_kwargs)
                return TrainingSeeds(env, streams[rank])

            return make

        venv = DummyVecEnv([factory(i) for i in range(n_envs)])
    return normalized(venv, hp)


def normalized(venv: Any, hp: PPOHyperparams) -> Any:
    """``venv`` under the observation (and, by ``hp``, reward) normalisation of training."""
    from stable_baselines3.common.vec_env import VecNormalize

    return VecNormalize(
        venv,
        norm_obs=True,
        norm_reward=hp.normalize_reward,
        gamma=float(hp.gamma),
        clip_obs=10.0,
    )


def validate(policy: NumpyPPOPolicy, scenario: str, episodes: int) -> float:
    """Mean episode RMSE on the first ``episodes`` validation seeds [nT]."""
    return float(np.mean(validation_rmse(policy, scenario, episodes)))


def train_ppo(
    scenario: str,
    timesteps: int | None,
    seed: int,
    out: Path,
    quick: bool = False,
    progress: bool = True,
    hyperparams: Path = HYPERPARAMS,
    total: bool = True,
) -> dict[str, Any]:
    """Train (or resume) PPO; keep the best validated policy as ``out/policy.npz``.

    ``timesteps`` None: :data:`TIMESTEPS`, or with ``quick`` ``QUICK.train_timesteps``;
    ``quick``: the sizes of :data:`agents.training.quick.QUICK` (about a minute). A resumed run
    trains up to ``timesteps`` in all (a run interrupted and rerun, or a retried task, ends where
    an unbroken one would: at the first rollout's end at or past ``timesteps``); with ``total``
    False, ``timesteps`` more.
    The checkpoint (:data:`CHECKPOINT`) is written as a set, so a kill leaves the previous
    checkpoint or the new one; the run is refused before training if a file it writes is an
    input."""
    check_output_set(out, (*CHECKPOINT, *OUTPUTS), [hyperparams])
    timesteps = sized(timesteps, TIMESTEPS, quick, QUICK.train_timesteps)
    with training_torch():
        return _train_ppo(scenario, timesteps, seed, out, quick, progress, hyperparams, total)


def _train_ppo(
    scenario: str,
    timesteps: int,
    seed: int,
    out: Path,
    quick: bool,
    progress: bool,
    hyperparams: Path,
    total: bool,
) -> dict[str, Any]:
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecNormalize

    hp = load_hyperparams(scenario, hyperparams)
    if quick:
        hp = quick_hyperparams(hp)
    venv = make_training_env(scenario, hp, seed)
    ckpt, stats = out / "checkpoint.zip", out / "vecnormalize.pkl"
    if ckpt.exists() and stats.exists():  # resume (pickle files this run wrote itself)
        try:
            venv = VecNormalize.load(str(stats), venv.venv)
            model = _quiet(PPO.load(str(ckpt), env=venv, device="cpu"))
        except Exception as e:  # a checkpoint of another version, or damaged by hand
            raise AeromagError(
                f"cannot resume from the checkpoint in {out} ({type(e).__name__}: "
                f"{e}); remove checkpoint.zip and vecnormalize.pkl to start "
                "afresh, or choose another --out"
            ) from None
    else:
        model = make_ppo(venv, hp, seed)
    curve = _load_curve(out)
    callback = _Callback(out, venv, scenario, hp, seed, curve, timesteps, progress)
    t0 = time.perf_counter()
    demos = None
    if (
        hp.pretrain is not None and not ckpt.exists()
    ):  # a fresh run: imitate, then validate at step 0
        demos = behaviour_clone(model, venv, hp, scenario, seed)
        if _clones(hp):
            demos.save(out / "demonstrations.npz")  # for a resumed run
        callback.init_callback(model)
        callback._validate()
    if _clones(hp):
        demos = demos if demos is not None else _demonstrations(out)
        callback.cloning = CloningTerm(model, venv, hp, demos, seed)
    steps = max(0, timesteps - model.num_timesteps) if total else timesteps
    model.learn(steps, callback=callback, reset_num_timesteps=not ckpt.exists())
    callback.checkpoint(model)
    venv.close()  # stops a prefetching worker
    summary = {
        "scenario": scenario,
        "timesteps": int(model.num_timesteps),
        "seed": seed,
        "train_seconds_this_run": time.perf_counter() - t0,
        "best_validation_rmse_nt": callback.best_rmse,
        "best_validation_score": callback.best,
        "hyperparams": {**hp.to_entry(), "version": hp.version},
        "curve": curve,
    }
    write_text(out / "training.json", json.dumps(summary, indent=2))
    return summary


def _clones(hp: PPOHyperparams) -> bool:
    """Whether behaviour cloning stays on during PPO (``pretrain.bc_minibatches`` > 0)."""
    return hp.pretrain is not None and hp.pretrain.bc_minibatches > 0


def _demonstrations(out: Path) -> Demonstrations:
    """The demonstrations of this run's pretraining, read back by a resumed run."""
    path = out / "demonstrations.npz"
    try:
        return Demonstrations.load(path)
    except (OSError, ValueError, KeyError) as e:
        raise AeromagError(
            f"cannot read the demonstrations {path} that pretrain.bc_minibatches needs "
            f"({type(e).__name__}: {e}); remove checkpoint.zip and vecnormalize.pkl to start "
            "afresh, or choose another --out"
        ) from None


@contextlib.contextmanager
def training_torch() -> Iterator[None]:
    """torch set up for training these tiny networks on the CPU, restored on exit: one thread
    (more only contend, and leave the other core to the batched environment and its prefetching
    worker) and no argument checks in ``torch.distributions`` (they re-check the Gaussian's
    parameters and every sample, about a quarter of PPO's own time per step here; results are
    unchanged, and a NaN action still fails in the environment's action check)."""
    import torch
    from torch.distributions import Distribution

    threads, checks = torch.get_num_threads(), Distribution._validate_args
    torch.set_num_threads(1)
    Distribution.set_default_validate_args(False)
    try:
        yield
    finally:
        torch.set_num_threads(threads)
        Distribution.set_default_validate_args(checks)


def make_ppo(venv: Any, hp: PPOHyperparams, seed: int) -> Any:
    """A fresh stable-baselines3 PPO (MLP policy, CPU) with the hyperparameters ``hp``."""
    from stable_baselines3 import PPO

    return _quiet(PPO("MlpPolicy", venv, seed=seed, device="cpu", verbose=0, **_ppo_kwargs(hp)))


def _quiet(model: Any) -> Any:
    """``model`` with a logger that writes nowhere: stable-baselines3's default makes an
    ``SB3-<date>`` folder in the temporary directory on every run, and never removes it."""
    from stable_baselines3.common.logger import Logger

    model.set_logger(Logger(folder=None, output_formats=[]))
    return model


def _ppo_kwargs(hp: PPOHyperparams) -> dict[str, Any]:
    kwargs = {k: getattr(hp, k) for k in SB3_PPO_KEYS}
    kwargs["learning_rate"] = _schedule(hp.learning_rate)
    # SB3's Adam (eps 1e-5) stepping all parameters in one foreach call: the same numbers
    # (tested bitwise), a third less optimizer time per minibatch on the CPU
    kwargs["policy_kwargs"] = {
        "net_arch": list(hp.net_arch),
        "optimizer_kwargs": {"eps": 1e-5, "foreach": True},
        "log_std_init": float(hp.log_std_init),  # initial exploration noise of the Gaussian
    }
    return kwargs


def _schedule(value: Any) -> Any:
    """A learning rate: a number, or ``"lin_<number>"`` (RL Zoo's notation) for one falling
    linearly from that number to 0 over the ``learn`` call (SB3's ``progress_remaining``, 1 → 0)."""
    if isinstance(value, str) and value.startswith("lin_"):
        try:
            start = float(value[4:])
        except ValueError:
            start = math.nan
        if not start > 0:
            raise AeromagError(f"learning_rate {value!r}: expected lin_<positive number>")
        return lambda progress_remaining: progress_remaining * start
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not value > 0:
        raise AeromagError(
            f"learning_rate must be a positive number or lin_<number>, got {value!r}"
        )
    return float(value)


def _load_curve(out: Path) -> list[dict[str, float]]:
    """The validation curve so far (written with every checkpoint, so a resumed run keeps it)."""
    path = out / "curve.json"
    return json.loads(path.read_text()) if path.exists() else []


def _callback_base() -> Any:
    from stable_baselines3.common.callbacks import BaseCallback

    return BaseCallback


def _selection_score(point: dict[str, float]) -> float:
    """What a validation point is chosen by: its score (``select_by``), else its RMSE."""
    return point.get("validation_score", point["validation_rmse_nt"])


class _Callback(_callback_base()):  # type: ignore[misc]
    """Progress bar, periodic validation (keeps the best export) and checkpoints."""

    def __init__(
        self,
        out: Path,
        venv: Any,
        scenario: str,
        hp: PPOHyperparams,
        seed: int,
        curve: list,
        total: int,
        progress: bool,
    ) -> None:
        super().__init__()
        self.out, self.venv, self.scenario, self.hp, self.seed = out, venv, scenario, hp, seed
        self.curve, self.total, self.progress = curve, total, progress
        best = min(curve, key=_selection_score, default=None)
        self.best = float("inf") if best is None else _selection_score(best)
        self.best_rmse = float("inf") if best is None else best["validation_rmse_nt"]
        self.validator = Validator(hp.select_by, scenario, hp.eval_episodes)
        self.next_eval = 0
        self.t0 = time.perf_counter()
        self.bar: Any = None
        self.cloning: CloningTerm | None = None

    def _on_training_start(self) -> None:
        from tqdm import tqdm

        self.bar = tqdm(
            total=self.total, unit="step", desc="train", disable=not self.progress or None
        )
        self.next_eval = self.model.num_timesteps + self.hp.eval_every

    def _on_rollout_start(self) -> None:
        if self.cloning is not None:  # after PPO's update (and once before the first rollout)
            self.cloning.step()

    def _on_step(self) -> bool:
        self.bar.update(self.training_env.num_envs)
        if self.model.num_timesteps >= self.next_eval:
            self.next_eval += self.hp.eval_every
            self._validate()
            self.checkpoint(self.model)
        return True

    def _on_training_end(self) -> None:
        if not self.curve or self.curve[-1]["timesteps"] != self.model.num_timesteps:
            self._validate()
        self.bar.close()

    def _validate(self) -> None:
        meta = {
            "scenario": self.scenario,
            "env_kwargs": dict(self.hp.env_kwargs),
            "seed": self.seed,
            "timesteps": int(self.model.num_timesteps),
            "hyperparams_version": self.hp.version,
        }
        candidate = export_policy(self.model, self.venv, self.out / "candidate.npz", meta)
        point = {
            "timesteps": int(self.model.num_timesteps),
            **self.validator(NumpyPPOPolicy.load(candidate)),
            "seconds": time.perf_counter() - self.t0,
        }
        score = _selection_score(point)
        self.curve.append(point)
        if score < self.best:
            self.best, self.best_rmse = score, point["validation_rmse_nt"]
            candidate.replace(self.out / "policy.npz")

    def checkpoint(self, model: Any) -> None:
        with output_set(self.out, CHECKPOINT) as stage:
            model.save(str(stage / "checkpoint.zip"))
            self.venv.save(str(stage / "vecnormalize.pkl"))
            write_text(stage / "curve.json", json.dumps(self.curve, indent=1))
