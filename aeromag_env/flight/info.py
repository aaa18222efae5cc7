"""``aeromag info FILE``: what a flight file holds, and whether the tools can use it.

:func:`describe` reads the file with the same reader and checks as every other tool
(:func:`aeromag_env.flight.files.load_flight` with ``needs=("tt",)``), so a file it calls usable
loads everywhere that its channels suffice.
"""

from __future__ import annotations

import json
import re
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from aeromag_env.errors import AeromagError, FlightFileError
from aeromag_env.flight.channels import Channels, choose_channels, with_altitude
from aeromag_env.flight.data import ALTITUDE_NAMES, ATTITUDE_NAMES, AUX_PREFIXES, Flight
from aeromag_env.flight.earth_model import model_mismatch
from aeromag_env.flight.files import file_format, load_flight
from aeromag_env.flight.formats.common import LABELS
from aeromag_env.flight.formats.detect import detect_format
from aeromag_env.flight.mount_choice import choose_mount, estimate_inputs_missing
from aeromag_env.flight.mounting import Mount
from aeromag_env.flight.quality import fault_report
from aeromag_env.flight.selection import select
from aeromag_env.flight.validation import (
    PathLike,
    format_nonfinite,
    nonfinite_report,
    truncated_list,
    validate,
)

#: Field groups in display order.
GROUPS = ("navigation", "attitude", "fluxgates", "scalars", "auxiliary", "truth", "other")

_NAVIGATION = {"tt", "lat", "lon", *ALTITUDE_NAMES, "year", "doy", "utm_x", "utm_y", "baro"}
_NAVIGATION_PREFIXES = ("ins_lat", "ins_lon", "ins_v", "ins_acc", "ins_w", "gps_")
_FLUX_RE = re.compile(r"^flux_[a-z]_")
_SCALAR_RE = re.compile(r"^mag_\d+_")
_MAX_LINES_LISTED = 50


@dataclass
class InfoReport:
    """Summary of one flight file.

    Attributes
    ----------
    lines : list of str
        Human-readable report, one entry per printed line.
    problems : list of str
        Warnings found, or the one-line error when the file is unusable.
    usable : bool
        The file loads (``read_flight(path, needs=("tt",))`` succeeds).
    summary : dict
        The same content as plain JSON-serialisable data (path, format, samples, duration_s,
        sample_rate_hz, date, attributes, fields by group, maneuver_windows, flight_line_count,
        flight_lines, nonfinite, faults: time gaps and spikes, :mod:`aeromag_env.flight.quality`;
        channels: the scalar, fluxgate and altitude ``compensate`` would choose and why,
        :mod:`aeromag_env.flight.channels`; earth_model_warnings: the chosen magnetometers against
        IGRF-14 at the file's position and date, :mod:`aeromag_env.flight.earth_model`; mounts:
        each fluxgate's mount estimated from the data, :mod:`aeromag_env.flight.mount_choice`).
    """

    lines: list[str]
    problems: list[str]
    usable: bool
    summary: dict[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        """``{"usable", "problems", **summary}`` for ``json.dumps``."""
        return {"usable": self.usable, "problems": list(self.problems), **self.summary}


def describe(
    path: PathLike,
    lines: tuple[float, ...] | None = None,
    segment: tuple[float, float] | None = None,
) -> InfoReport:
    """Summarise a flight file (any format of :mod:`aeromag_env.flight.files`); never raises for
    a bad file.

    Parameters
    ----------
    path : str or PathLike
    lines, segment : summarise only these flight lines and ``(T0, T1)`` [s]
        (:func:`aeromag_env.flight.selection.select`; a line or segment the file does not hold
        raises :class:`~aeromag_env.errors.AeromagError`)

    Returns
    -------
    InfoReport
        ``usable=False`` with the one-line error as the only problem when the file cannot be
        read or fails the basic checks (structure, ``tt``); ``usable=False`` with the summary
        when a channel present is in implausible units (µT, radians…), since every consumer of
        that channel would refuse it.
    """
    head: dict[str, Any] = {"path": str(path), "format": _format_label(path)}
    title = f"file: {head['path']} ({head['format']})"
    try:
        flight, problems = load_flight(path, needs=("tt",))
    except FlightFileError as exc:
        return InfoReport([title, f"error: {exc}"], [str(exc)], False, head)
    if lines is not None or segment is not None:
        chosen = select(flight, lines, segment)
        flight, head["selection"] = chosen.flight, chosen.report
        title += f", {flight.attrs.get('selection', 'selection: every sample')}"
    usable = True
    try:  # a unit problem is fatal only for channels a consumer needs: here, all present
        validate(flight, path, present_needs(flight))
    except FlightFileError as exc:
        problems, usable = [f"unusable: {exc}", *problems], False
    summary = {**head, **summarise(flight)}
    problems = [*problems, *summary["channel_warnings"], *summary["earth_model_warnings"]]
    return InfoReport([title, *_format_lines(summary, problems)], problems, usable, summary)


def _format_label(path: PathLike) -> str:
    """The format found from the content (``HDF5``, ``MAT5``…), else from the suffix."""
    try:
        return LABELS.get(detect_format(Path(path)), "unknown")
    except (FlightFileError, OSError):
        kind = file_format(path)
        return kind.upper() if kind else "unknown"


def present_needs(flight: Flight) -> list[str]:
    """``needs`` tokens for every fluxgate, scalar, position and attitude present.

    Not the date: one that is unreadable or outside IGRF-14's years is listed among the
    problems, and only the commands that evaluate the Earth-field model refuse it (``tl`` and
    ``convert`` use the file as it is)."""
    needs = [*flight.fluxgates(), *flight.scalars()]
    if all(nm in flight for nm in ATTITUDE_NAMES):
        needs.append("attitude")
    if "lat" in flight and "lon" in flight and flight.altitude_name():
        needs.append("position")
    return needs


def summarise(flight: Flight) -> dict[str, Any]:
    """Plain-data summary of a validated flight (see :class:`InfoReport`)."""
    rate = flight.sample_rate_hz
    channels = choose_channels(flight)
    return {
        "samples": flight.n,
        "duration_s": flight.duration_s,
        "sample_rate_hz": rate if np.isfinite(rate) else None,
        "date": _date_text(flight),
        "attributes": list(flight.attrs),
        "fields": group_fields(flight.names),
        "maneuver_windows": [
            {"id": mid, "t_start_s": t0, "t_end_s": t1} for mid, t0, t1 in flight.maneuver_windows()
        ],
        "flight_line_count": _count_lines(flight),
        "flight_lines": _flight_lines(flight),
        "nonfinite": nonfinite_report(flight),
        "faults": fault_report(flight),
        "channels": channels.to_dict(),
        "channel_warnings": list(channels.warnings),
        "earth_model_warnings": _model_warnings(flight, channels),
        "mounts": estimated_mounts(flight),
    }


def _model_warnings(flight: Flight, channels: Channels) -> list[str]:
    """The chosen magnetometers against the Earth-field model (position, date, units), as
    ``compensate`` checks them (:func:`~aeromag_env.flight.earth_model.model_mismatch`)."""
    scalar, flux = (c.name if c else None for c in (channels.scalar, channels.fluxgate))
    found = model_mismatch(with_altitude(flight, channels.altitude), scalar, flux)
    return [found] if found else []


def estimated_mounts(flight: Flight) -> dict[str, dict[str, Any]]:
    """Each fluxgate's mount as the data indicate: angles [deg], angle from the body axes [deg]
    and residual [nT] (``aeromag compensate --mount auto`` would use it), or why not."""
    missing = estimate_inputs_missing(flight)
    out: dict[str, dict[str, Any]] = {}
    for gate in flight.fluxgates():
        if missing:
            out[gate] = {"error": f"not estimated: no {missing} in the file"}
            continue
        try:
            choice = choose_mount(flight, gate, "auto", relevant=False)
        except (AeromagError, ValueError, KeyError) as exc:  # e.g. a date beyond IGRF
            out[gate] = {"error": f"not estimated: {exc}"}
            continue
        est = choice.estimate
        if est is None:
            out[gate] = {"error": choice.reason.split(";")[0]}
            continue
        angle = Mount.identity().angle_to_deg(est)
        out[gate] = {**est.to_dict(), "angle_from_body_deg": angle}
    return out


def group_fields(names: list[str]) -> dict[str, list[str]]:
    """Field names by group (:data:`GROUPS`), in file order within each group."""
    groups: dict[str, list[str]] = {group: [] for group in GROUPS}
    for name in names:
        groups[_group_of(name)].append(name)
    return groups


def _group_of(name: str) -> str:
    """The display group of one field name."""
    if name.startswith("truth_"):
        return "truth"
    if name.startswith(AUX_PREFIXES):
        return "auxiliary"
    if name in ATTITUDE_NAMES:
        return "attitude"
    if _FLUX_RE.match(name):
        return "fluxgates"
    if _SCALAR_RE.match(name):
        return "scalars"
    if name in _NAVIGATION or name.startswith(_NAVIGATION_PREFIXES):
        return "navigation"
    return "other"


def _date_text(flight: Flight) -> str | None:
    """ISO date (with the time if not midnight) of the flight, None if unknown."""
    try:
        date = flight.date()
    except (KeyError, ValueError, OverflowError):
        return None
    return date.date().isoformat() if date.time() == date.min.time() else date.isoformat()


def _no_date_text(problems: list[str]) -> str:
    """Why the date line shows no date: an unusable one (listed among the problems) or none."""
    if any(p.startswith(("unreadable date", "unusable date")) for p in problems):
        return "unusable (see problems)"
    return "unknown (no date attribute, no year/doy fields)"


def _count_lines(flight: Flight) -> int:
    """Number of distinct finite values of the ``line`` field (0 without one)."""
    if "line" not in flight:
        return 0
    return int(np.unique(flight["line"][np.isfinite(flight["line"])]).size)


def _flight_lines(flight: Flight) -> list[dict[str, Any]]:
    """The first 50 line ids in order of appearance, with their time spans and sample counts."""
    if "line" not in flight:
        return []
    line = flight["line"]
    ids, first = np.unique(line[np.isfinite(line)], return_index=True)
    out = []
    for value in ids[np.argsort(first)][:_MAX_LINES_LISTED]:
        k = np.flatnonzero(line == value)
        out.append(
            {
                "id": int(value) if float(value).is_integer() else float(value),
                "t_start_s": float(flight.tt[k[0]]),
                "t_end_s": float(flight.tt[k[-1]]),
                "samples": int(k.size),
            }
        )
    return out


def _format_lines(summary: dict[str, Any], problems: list[str]) -> list[str]:
    """The printed report of a usable file (after the title line)."""
    rate = summary["sample_rate_hz"]
    lines = [
        f"samples: {summary['samples']}",
        f"duration: {summary['duration_s']:.6g} s",
        f"sample rate: {rate:.6g} Hz" if rate is not None else "sample rate: –",
        f"date: {summary['date'] or _no_date_text(problems)}",
        f"attributes: {truncated_list(summary['attributes']) or 'none'}",
        f"fields ({sum(map(len, summary['fields'].values()))}):",
    ]
    lines += [
        f"  {group} ({len(names)}): {truncated_list(names, 40)}"
        for group, names in summary["fields"].items()
        if names
    ]
    windows = summary["maneuver_windows"]
    lines.append(f"maneuver windows: {len(windows)}")
    lines += [f"  {w['id']}: {w['t_start_s']:.6g}–{w['t_end_s']:.6g} s" for w in windows]
    flight_lines = summary["flight_lines"]
    lines.append(f"flight lines: {summary['flight_line_count']}")
    lines += [
        f"  {fl['id']}: {fl['t_start_s']:.6g}–{fl['t_end_s']:.6g} s ({fl['samples']} samples)"
        for fl in flight_lines
    ]
    nonfinite = summary["nonfinite"]
    lines.append(f"non-finite samples: {f'{len(nonfinite)} field(s)' if nonfinite else 'none'}")
    lines += [f"  {format_nonfinite(name, entry)}" for name, entry in nonfinite.items()]
    faults = summary["faults"]
    lines.append(f"continuous segments: {faults['segments']} ({faults['gap_count']} time gap(s))")
    lines.append(f"spikes: {sum(e['count'] for e in faults['spikes'].values()) or 'none'}")
    lines += _channel_lines(summary["channels"], summary["mounts"])
    lines.append(f"problems: {len(problems) or 'none'}")
    return lines + [f"  - {problem}" for problem in problems]


def _channel_lines(channels: dict[str, Any], mounts: dict[str, dict[str, Any]]) -> list[str]:
    """The channels ``compensate`` would choose, and each fluxgate's estimated mount."""
    lines = ["channels (auto):"]
    for kind, entry in channels.items():
        lines.append(f"  {kind}: {entry['name']} ({entry['reason']})" if entry else f"  {kind}: –")
    lines.append(f"fluxgate mounts (estimated from attitude and IGRF): {len(mounts) or 'none'}")
    for gate, m in mounts.items():
        if "error" in m:
            lines.append(f"  {gate}: {m['error']}")
            continue
        angles = ", ".join(f"{m[k]:.1f}" for k in ("roll_deg", "pitch_deg", "yaw_deg"))
        lines.append(
            f"  {gate}: roll/pitch/yaw {angles}° ({m['angle_from_body_deg']:.1f}° from the body "
            f"axes), residual {m['residual_nt']:.0f} nT over {m['samples']} samples"
        )
    return lines


def main_info(
    path: str,
    as_json: bool,
    lines: tuple[float, ...] | None = None,
    segment: tuple[float, float] | None = None,
) -> int:
    """Print the report of ``path`` (of its ``lines`` and ``segment``) to stdout (JSON if
    ``as_json``); 0 if usable, else 2 with the error as one line ``aeromag info: error: ...`` on
    stderr. An unreadable file has no text report (its JSON report still goes to stdout); a
    file in implausible units keeps its summary on stdout."""
    report = describe(path, lines, segment)
    if as_json:
        print(json.dumps(report.to_dict(), indent=2, ensure_ascii=False, allow_nan=False))
    elif report.summary.keys() - {"path", "format"}:  # a summary, not just the failed read
        print("\n".join(report.lines))
    if report.usable:
        return 0
    print(f"aeromag info: error: {report.problems[0].removeprefix('unusable: ')}", file=sys.stderr)
    return 2
