"""Convert a flight file to another format: :func:`convert`, the job of ``aeromag convert``.

The input's format is found from its content, the output's from its suffix; fields with an
alias get the SGL 2020 names (the aliases are recorded); the input is never overwritten and the
output is written atomically.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from aeromag_env.flight.data import Flight
from aeromag_env.flight.files import convert_flight
from aeromag_env.flight.validation import PathLike


@dataclass(frozen=True)
class ConversionResult:
    """What :func:`convert` wrote.

    Attributes
    ----------
    flight : Flight
        The flight written (our field names; the aliases in ``attrs["aliases"]``).
    path : Path
        The file written.
    warnings : tuple of str
        The reader's warnings (aliases applied, skipped items, non-finite samples…).
    """

    flight: Flight
    path: Path
    warnings: tuple[str, ...]


def convert(source: PathLike, target: PathLike) -> ConversionResult:
    """Read ``source`` (any format) and write it to ``target`` (format by suffix), as ``aeromag
    convert`` does.

    Raises
    ------
    FlightFileError
        Unreadable input, unknown output suffix, output equal to the input, or a failed write.
    """
    flight, problems = convert_flight(source, target)
    return ConversionResult(flight, Path(target), tuple(problems))
