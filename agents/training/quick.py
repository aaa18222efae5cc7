"""What ``--quick`` means, in one place: a run of about a minute on a 2-core machine.

``aeromag train --quick`` (every learner), ``aeromag tune --quick``, ``aeromag bench --quick``
and the experiments' ``--quick`` apply :data:`QUICK` after their defaults: its sizes replace
the defaults (of the hyperparameter files too), whatever those say; a size the caller gives
(``--timesteps 64``) is kept. For tests and a first look, not for figures: the trained
policies and the measured speeds of a quick run mean little.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:  # the table itself imports nothing heavy (the experiments read it)
    from agents.training.hyperparameters import PPOHyperparams
    from agents.training.learner_hyperparameters import LearnerHyperparams


def _frozen(**values: Any) -> Any:
    return field(default_factory=lambda: MappingProxyType(values))


@dataclass(frozen=True, kw_only=True)
class QuickPreset:
    """The sizes of a quick run.

    Attributes
    ----------
    ppo : PPO hyperparameters (train, tune, bench): two environments, tiny rollouts, two
        validation flights, no prefetching worker
    pretrain : the pretraining's (one round of 256 demonstration steps, one epoch), its cloning
        term on the demonstrations of every scenario: 256 steps fly parts of two flights, which
        may miss every scenario an entry's ``bc_scenarios`` names
    learners : every other learner's (train, tune): a few thousand steps of two environments,
        one validation flight per scenario of the suite, no prefetching worker
    cmaes : CMA-ES's search (``algo``): three candidates per generation, one flight of each
        scenario of the suite, one normalisation flight
    train_timesteps : environment steps of ``aeromag train`` per seed, at most
    tune_samples, tune_timesteps, tune_reports : ``aeromag tune``'s trials, environment steps
        per trial and validations per trial, at most
    bench_repeats : repeats of the fast benchmarks
    bench_filter_samples : samples of the filter benchmarks
    bench_ppo_timesteps : PPO steps measured with 8 environments (once)
    bench_ppo64 : whether PPO with 64 environments is measured (simulating 4 × 64 flights and
        a rollout of 64 × n_steps steps for each variant: most of a quick run)
    bench_flight_hours : the benchmarks' flight [h] (discovery on it; the simulation figures
        are per flight-hour either way)
    bench_memory : whether the 10-hour memory figure is measured (a fresh process: half a
        minute)
    bench_ray_flights : flights of the Ray figures (``--ray``)
    episodes : evaluation flights per scenario of the experiments
    scenarios : scenarios the evaluation experiments fly (the first of the list)
    seeds : simulation seeds of the experiments that sweep them
    """

    ppo: Mapping[str, Any] = _frozen(
        n_envs=2, n_steps=64, batch_size=64, eval_every=512, eval_episodes=2, prefetch=False
    )
    pretrain: Mapping[str, Any] = _frozen(steps=256, epochs=1, dagger_rounds=1, bc_scenarios=None)
    learners: Mapping[str, Any] = _frozen(
        timesteps=2048, n_envs=2, eval_every=1024, eval_episodes=7, prefetch=False
    )
    cmaes: Mapping[str, Any] = _frozen(popsize=3, flights=7, normalisation_flights=1)
    train_timesteps: int = 2048
    tune_samples: int = 2
    tune_timesteps: int = 1024
    tune_reports: int = 3
    bench_repeats: int = 3
    bench_filter_samples: int = 1000
    bench_ppo_timesteps: int = 2048
    bench_ppo64: bool = False
    bench_flight_hours: float = 0.25
    bench_memory: bool = False
    bench_ray_flights: int = 16
    episodes: int = 2
    scenarios: int = 2
    seeds: int = 2


#: The quick preset.
QUICK = QuickPreset()


def quick_hyperparams(hp: PPOHyperparams) -> PPOHyperparams:
    """``hp`` with :data:`QUICK`'s PPO sizes (and its pretraining's, when it pretrains)."""
    changes: dict[str, Any] = dict(QUICK.ppo)
    if hp.pretrain is not None:
        changes["pretrain"] = dict(QUICK.pretrain)
    return hp.with_values(**changes)


def quick_learner(hp: LearnerHyperparams) -> LearnerHyperparams:
    """``hp`` (a learner of ``learners.json``) with :data:`QUICK`'s sizes (and CMA-ES's search
    sizes for CMA-ES)."""
    changes: dict[str, Any] = dict(QUICK.learners)
    if hp.learner == "cmaes":
        changes["algo"] = dict(QUICK.cmaes)
    return hp.with_values(**changes)


def sized(given: int | None, default: int, quick: bool, quick_size: int) -> int:
    """A size: the one the caller gave, else ``quick_size`` with ``quick``, else ``default``."""
    if given is not None:
        return given
    return quick_size if quick else default
