"""Validate and summarise a flight file: :func:`info`, the job of ``aeromag info``.

The summary (:func:`aeromag_env.flight.info.describe`) never raises for a bad file: an unusable
file is a report whose ``usable`` is false, with the reason as its only problem.
"""

from __future__ import annotations

from pathlib import Path

from aeromag_env.flight.info import InfoReport, describe
from aeromag_env.flight.validation import PathLike
from aeromag_env.jobs.limits import check_lines, check_window


def info(
    path: PathLike,
    *,
    lines: tuple[float, ...] | None = None,
    segment_s: tuple[float, float] | None = None,
) -> InfoReport:
    """The report of a flight file (of its ``lines`` and ``segment_s``), as ``aeromag info``
    shows it.

    Parameters
    ----------
    path : str or PathLike
        A flight file (HDF5, CSV, Geosoft XYZ or MATLAB ``.mat``).
    lines : tuple of float or None
        Summarise only these flight lines (ids of the ``line`` field).
    segment_s : (float, float) or None
        Summarise only the samples with ``T0 ≤ tt ≤ T1`` [s].

    Returns
    -------
    InfoReport
        ``usable``, ``problems`` (warnings, or the one-line error of an unusable file), the
        summary and its lines of text.

    Raises
    ------
    AeromagError
        Unusable ``lines`` or ``segment_s``, or a line or segment the file does not hold.
    """
    check_lines("lines", lines)
    check_window("segment_s", segment_s)
    return describe(Path(path), lines, segment_s)
