"""``aeromag tune``: search PPO hyperparameters with Ray Tune (:mod:`agents.tune`; ``agents``
and Ray are imported when the command runs), print what it found."""

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
        The summary of :func:`agents.tune.tune_ppo`.
    """
    limits.check_tune(args)
    try:
        from agents.ppo import HYPERPARAMS
        from agents.tune import tune_ppo
        from agents.tune_space import SPACE
    except ImportError as e:
        raise AeromagError(
            f"aeromag tune needs the rl and ray extras (pip install 'aeromag-env[rl,ray]'): {e}"
        ) from None
    address = None if args.ray in (None, "local") else args.ray
    space = Path(args.space) if args.space else SPACE
    hyperparams = Path(args.hyperparams) if args.hyperparams else HYPERPARAMS
    return tune_ppo(
        args.scenario,
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
    return (
        f"{len(trials)} trials ({stopped} stopped early by ASHA, {failed} failed) in "
        f"{summary['seconds']:.0f} s on {summary['cpus']} CPUs\n"
        f"best: trial {best['trial']}, validation RMSE {best['best_validation_rmse_nt']:.3g} nT "
        f"({config})\n"
        f"hyperparameters: {out}/ppo.json (aeromag train --scenario {summary['scenario']} "
        f"--hyperparams {out}/ppo.json); every trial: {out}/tune.json"
    )
