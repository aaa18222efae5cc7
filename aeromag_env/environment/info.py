"""The ``info`` of a step, built in one place from one table.

Every entry of a step's info comes from the step's outcome vector (:data:`OUT
<aeromag_env.environment.layout.OUT>`), the filter's counters (:data:`INTS
<aeromag_env.compensation.kernel_layout.INTS>`) or the flight's seed; :data:`INFO` says which,
in the order of the dict. The single environment (:func:`info`), the vector environment's
batched infos (:func:`put_infos`) and its per-environment rows (:func:`info_rows`, for
stable-baselines3) all read it.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np

from aeromag_env.compensation.kernel_layout import INTS
from aeromag_env.environment.layout import OUT


class InfoEntry(NamedTuple):
    """One key of the info dict and where its value is."""

    key: str
    source: str  #: ``out`` (a float of the outcome), ``ints`` (a counter) or ``seed``
    slot: int  #: its index in that vector (-1 for the seed)
    description: str


#: The info of every step, in order.
INFO = (
    InfoEntry("rmse_window_nt", "out", OUT.rmse, "RMS error over the window [nT]"),
    InfoEntry("ror", "out", OUT.ror, "ROR at the end of the window"),
    InfoEntry("qoq", "out", OUT.qoq, "QOQ at the end of the window"),
    InfoEntry("q_scale", "out", OUT.q_scale, "cumulative Q scale relative to Q(0)"),
    InfoEntry("r_scale", "out", OUT.r_scale, "cumulative R scale relative to R(0)"),
    InfoEntry("q_permanent_scale", "out", OUT.qp_scale, "cumulative Q scale of T_p"),
    InfoEntry("sample", "ints", INTS.k, "samples flown"),
    InfoEntry("flight_seed", "seed", -1, "the seed of the episode's flight"),
    InfoEntry("episode_rmse_nt", "out", OUT.episode_rmse, "the episode's RMSE so far [nT]"),
    InfoEntry("divergences", "ints", INTS.div, "restarts after a divergence"),
    InfoEntry("outliers_rejected", "ints", INTS.out, "samples the outlier gate skipped"),
)
#: The keys, in order.
INFO_KEYS = tuple(e.key for e in INFO)


def info(out: np.ndarray, ints: np.ndarray, seed: int) -> dict[str, Any]:
    """The info of one environment: ``out`` (N_OUT,) its outcome, ``ints`` (N_INT,) its
    filter's counters, ``seed`` its flight's seed (floats and ints)."""
    values = {"out": out.tolist(), "ints": ints.tolist()}
    return {e.key: int(seed) if e.source == "seed" else values[e.source][e.slot] for e in INFO}


def info_rows(out: np.ndarray, ints: np.ndarray, seeds: np.ndarray) -> list[dict[str, Any]]:
    """:func:`info` of each of N environments: ``out`` (N, N_OUT), ``ints`` (N, N_INT),
    ``seeds`` (N,)."""
    columns = [_column(e, out, ints, seeds).tolist() for e in INFO]
    return [dict(zip(INFO_KEYS, values, strict=True)) for values in zip(*columns, strict=True)]


def put_infos(
    infos: dict[str, Any],
    out: np.ndarray,
    ints: np.ndarray,
    seeds: np.ndarray,
    mask: np.ndarray,
    put: Any,
) -> None:
    """The infos of the environments of ``mask`` (N,) bool into Gymnasium's batched layout,
    each key through ``put(infos, key, values (N,), mask)``."""
    for e in INFO:
        put(infos, e.key, _column(e, out, ints, seeds), mask)


def _column(e: InfoEntry, out: np.ndarray, ints: np.ndarray, seeds: np.ndarray) -> np.ndarray:
    if e.source == "seed":
        return seeds
    return (out if e.source == "out" else ints)[:, e.slot]
