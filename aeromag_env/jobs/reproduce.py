"""Reproduce the paper's figures 3–5: :func:`reproduce`, the job of ``aeromag reproduce-paper``
(the experiment itself is :func:`aeromag_env.compensation.paper.reproduce_paper`)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from aeromag_env.compensation.paper import reproduce_paper
from aeromag_env.jobs.limits import check_seed


def reproduce(
    out: str | Path = "results/paper", *, quick: bool = False, seed: int = 2014
) -> dict[str, Any]:
    """Run the paper's setting on a simulated flight and compare with its claims; writes
    ``report.json``, ``fig3/4/5_*.png`` and ``flight.h5`` to ``out``; returns the report.

    ``quick``: one calibration box instead of 30 minutes; ``seed`` in ``[0, 2³² − 1]``.
    """
    check_seed("seed", seed)
    return reproduce_paper(Path(out), quick=quick, seed=seed)
