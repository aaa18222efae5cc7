"""``aeromag tune``: search a learner's hyperparameters with Ray Tune (:mod:`agents.tune` for
PPO, :mod:`agents.tune_learners` for the others; ``agents`` and Ray are imported when the command
runs), print what it found."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from aeromag_env.cli import limits
from aeromag_env.errors import AeromagError


def run_tune(args: argparse.Namespace) -> dict[str, Any]:
    """Check the options, run the search, return the summary (``tune.json``'s content).

    Parameters
    ----------
    args : argparse.Namespace
        Parsed arguments of ``aeromag tune``.

    Returns
    -------
    dict
        The summary of :func:`agents.tune.tune_ppo` (``--learner ppo``) or
        :func:`agents.tune_learners.tune_learner`.
    """
    limits.check_tune(args)
    if args.learner != "ppo" and args.scenario not in (None, "suite"):
        raise AeromagError(
            f"--learner {args.learner} trains the general tuner on the suite; --scenario "
            f"{args.scenario} is for --learner ppo"
        )
    try:
        from agents import learners
        from agents.ppo import HYPERPARAMS
        from agents.tune import tune_ppo
        from agents.tune_learners import tune_learner
        from agents.tune_space import LEARNER_SPACES, SPACE
    except ImportError as e:
        raise AeromagError(
            f"aeromag tune needs the rl and ray extras (pip install 'aeromag-env[rl,ray]'): {e}"
        ) from None
    address = None if args.ray in (None, "local") else args.ray
    ppo = args.learner == "ppo"
    space = Path(args.space) if args.space else SPACE if ppo else LEARNER_SPACES
    base = HYPERPARAMS if ppo else learners.HYPERPARAMS
    hyperparams = Path(args.hyperparams) if args.hyperparams else base
    if not ppo:
        return tune_learner(
            args.learner,
            Path(args.out),
            space_path=space,
            samples=args.samples,
            timesteps=args.timesteps,
            seed=args.seed,
            quick=args.quick,
            ray_address=address,
            hyperparams=hyperparams,
        )
    return tune_ppo(
        args.scenario or "nonstationary",
        space,
        args.samples,
        args.timesteps,
        Path(args.out),
        seed=args.seed,
        quick=args.quick,
        ray_address=address,
        hyperparams=hyperparams,
    )


def tune_summary(summary: dict[str, Any], out: str) -> str:
    """The lines ``aeromag tune`` prints: the trials, the best, where it is written."""
    trials, best = summary["trials"], summary["best"]
    stopped = sum(t["stopped_by_asha"] for t in trials)
    failed = sum(t["error"] is not None for t in trials)
    config = ", ".join(
        f"{k} {v:.3g}" if isinstance(v, float) else f"{k} {v}" for k, v in best["config"].items()
    )
    head = (
        f"{len(trials)} trials ({stopped} stopped early by ASHA, {failed} failed) in "
        f"{summary['seconds']:.0f} s on {summary['cpus']} CPUs\n"
    )
    if "learner" in summary:
        learner = summary["learner"]
        return (
            f"{head}best: trial {best['trial']}, validation score "
            f"{best['best_validation_score']:.3g} ({summary['select_by']}; {config})\n"
            f"hyperparameters: {out}/learners.json (aeromag train --learner {learner} "
            f"--hyperparams {out}/learners.json); every trial: {out}/tune.json"
        )
    return (
        f"{head}best: trial {best['trial']}, validation RMSE "
        f"{best['best_validation_rmse_nt']:.3g} nT ({config})\n"
        f"hyperparameters: {out}/ppo.json (aeromag train --scenario {summary['scenario']} "
        f"--hyperparams {out}/ppo.json); every trial: {out}/tune.json"
    )
