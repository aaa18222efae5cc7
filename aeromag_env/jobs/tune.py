"""Search a learner's hyperparameters with Ray Tune: :func:`tune`, the job of ``aeromag tune``.

PPO (:func:`agents.search.ppo.tune_ppo`) trains each trial on a scenario and writes
``out/ppo.json``; the other learners (:func:`agents.search.learners.tune_learner`) train on the
suite and write ``out/learners.json``; both write every trial to ``out/tune.json``. Trials
validate on the validation seeds only, and ASHA stops those that validate badly.

Rerunning a request finishes it: a search that was interrupted runs again from its first
trial (Tune's trials keep no checkpoint), and one whose ``tune.json`` in ``out`` records the same
request is not run again (:func:`finished_search`).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from aeromag_env.errors import AeromagError
from aeromag_env.jobs.limits import MAX_SAMPLES, MAX_TIMESTEPS, check_count, check_seed


@dataclass(frozen=True, kw_only=True)
class TuneRequest:
    """What a hyperparameter search is asked for (validated by :meth:`check`).

    Attributes
    ----------
    out : Path
        The folder of the best hyperparameters and ``tune.json``.
    learner : str
        One of :data:`agents.training.LEARNERS` but ``cmaes`` (not searched).
    scenario : str or None
        PPO's training scenario (None: ``nonstationary``); the others train on the suite.
    space : Path or None
        The search space file (None: the shipped one of the learner).
    samples : int or None
        Trials (None: 16; ``quick``: 2).
    timesteps : int or None
        Environment steps per trial (None: the learner's default).
    seed : int
        The sampling and training seed.
    quick : bool
        About a minute (:mod:`agents.training.quick`).
    ray : str or None
        None or ``local``: a Ray started here with this machine's cores; else a cluster's
        address.
    hyperparams : Path or None
        The base hyperparameter file (None: the shipped one).
    """

    out: Path
    learner: str = "ppo"
    scenario: str | None = None
    space: Path | None = None
    samples: int | None = None
    timesteps: int | None = None
    seed: int = 0
    quick: bool = False
    ray: str | None = None
    hyperparams: Path | None = None

    def check(self) -> None:
        """One-line errors for unusable arguments, before Ray starts."""
        from agents.training import training_scenario

        training_scenario(self.learner, self.scenario)
        check_seed("seed", self.seed)
        if self.timesteps is not None:
            check_count(
                "timesteps",
                self.timesteps,
                1,
                MAX_TIMESTEPS,
                "environment steps",
                "10⁹ is 333× the shipped policies' 3e6 and days of CPU time",
            )
        if self.samples is not None:
            check_count(
                "samples",
                self.samples,
                1,
                MAX_SAMPLES,
                "trials",
                "the best of 1000 random samples is in the best 0.3 % of the space with 95 % "
                "probability",
            )


@dataclass(frozen=True)
class TuneResult:
    """What :func:`tune` found.

    Attributes
    ----------
    summary : dict
        ``tune.json``'s content: every trial (its configuration, validation score, whether ASHA
        stopped it, its error) and the best.
    hyperparams : Path
        The best trial's hyperparameter file (``ppo.json`` or ``learners.json``).
    finished : bool
        The search had already been run to the end with the same request (``out/tune.json``
        records it): nothing was run or written.
    """

    summary: dict[str, Any]
    hyperparams: Path
    finished: bool = False


def tune(
    out: str | Path,
    *,
    learner: str = "ppo",
    scenario: str | None = None,
    space: str | Path | None = None,
    samples: int | None = None,
    timesteps: int | None = None,
    seed: int = 0,
    quick: bool = False,
    ray: str | None = None,
    hyperparams: str | Path | None = None,
) -> TuneResult:
    """Search ``learner``'s hyperparameters, as ``aeromag tune`` does.

    Parameters
    ----------
    out : str or Path
        The output folder.
    learner, scenario, space, samples, timesteps, seed, quick, ray, hyperparams
        See :class:`TuneRequest`.

    Returns
    -------
    TuneResult

    Raises
    ------
    AeromagError
        Bad arguments or missing extras (rl, ray), one line, before any trial.
    """
    request = TuneRequest(
        out=Path(out),
        learner=learner,
        scenario=scenario,
        space=None if space is None else Path(space),
        samples=samples,
        timesteps=timesteps,
        seed=seed,
        quick=quick,
        ray=ray,
        hyperparams=None if hyperparams is None else Path(hyperparams),
    )
    request.check()
    return run_tune(request)


def run_tune(req: TuneRequest) -> TuneResult:
    """Do the work of :func:`tune` for a checked request."""
    try:
        from agents.search.learners import tune_learner
        from agents.search.ppo import tune_ppo
        from agents.search.space import LEARNER_SPACES, SPACE
        from agents.training import PPO_SCENARIO, learners, ppo
    except ImportError as e:
        raise AeromagError(
            f"aeromag tune needs the rl and ray extras (pip install 'aeromag-env[rl,ray]'): {e}"
        ) from None
    address = None if req.ray in (None, "local") else req.ray
    written = req.out / ("ppo.json" if req.learner == "ppo" else "learners.json")
    done = finished_search(req)
    if done is not None:
        return TuneResult(done, written, finished=True)
    if req.learner != "ppo":
        summary = tune_learner(
            req.learner,
            req.out,
            space_path=req.space or LEARNER_SPACES,
            samples=req.samples,
            timesteps=req.timesteps,
            seed=req.seed,
            quick=req.quick,
            ray_address=address,
            hyperparams=req.hyperparams or learners.HYPERPARAMS,
        )
        return TuneResult(summary, req.out / "learners.json")
    summary = tune_ppo(
        req.scenario or PPO_SCENARIO,
        req.space or SPACE,
        req.samples,
        req.timesteps,
        req.out,
        seed=req.seed,
        quick=req.quick,
        ray_address=address,
        hyperparams=req.hyperparams or ppo.HYPERPARAMS,
    )
    return TuneResult(summary, req.out / "ppo.json")


def finished_search(req: TuneRequest) -> dict[str, Any] | None:
    """The ``tune.json`` of a search in ``req.out`` that ran to its end with the same request
    (learner, scenario, trials, steps per trial when given, seed, quick, space and base files),
    with the hyperparameter file it wrote; else None (no search there, or another one: it is
    run, and its outputs replace the old ones)."""
    from agents.search.ppo import SAMPLES
    from agents.search.space import LEARNER_SPACES, SPACE, recorded_path
    from agents.training import PPO_SCENARIO, learners, ppo
    from agents.training.quick import QUICK, sized

    path = req.out / "tune.json"
    written = req.out / ("ppo.json" if req.learner == "ppo" else "learners.json")
    try:
        summary = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(summary, dict) or not written.exists():
        return None
    ppo_search = req.learner == "ppo"
    space = req.space or (SPACE if ppo_search else LEARNER_SPACES)
    base = req.hyperparams or (ppo.HYPERPARAMS if ppo_search else learners.HYPERPARAMS)
    asked = {
        "learner": req.learner,
        "scenario": (req.scenario or PPO_SCENARIO) if ppo_search else None,
        "samples": sized(req.samples, SAMPLES, req.quick, QUICK.tune_samples),
        "seed": req.seed,
        "quick": req.quick,
        "space_file": recorded_path(space),
        "hyperparams": recorded_path(base),
    }
    held = {**summary, "learner": summary.get("learner", "ppo")}
    held.setdefault("scenario", None)
    same = all(held.get(key) == value for key, value in asked.items())
    if req.timesteps is not None:
        same = same and held.get("timesteps") == req.timesteps
    return summary if same and len(summary.get("trials", ())) == asked["samples"] else None
