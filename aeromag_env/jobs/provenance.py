"""What a run used, for ``report.json``: the input file's hash and format, the channels and the
fluxgate mount chosen (and why), the flight's segments and flagged samples, its date and where
that came from, and the Earth-field model with its version.

:func:`choose_inputs` is the one place ``compensate`` and ``discover`` pick their channels
(:mod:`aeromag_env.flight.channels`) and fluxgate mount (:mod:`aeromag_env.flight.mount_choice`)
and say the warnings of both, one line each; :func:`provenance` turns the result into the
report's blocks.
"""

from __future__ import annotations

import hashlib
import importlib.metadata
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from aeromag_env import errors
from aeromag_env.errors import AeromagError
from aeromag_env.flight.channels import KINDS, Channels, choose_channels, with_altitude
from aeromag_env.flight.data import Flight
from aeromag_env.flight.earth_model import model_mismatch
from aeromag_env.flight.files import load_flight
from aeromag_env.flight.formats.detect import detect_format
from aeromag_env.flight.mount_choice import (
    MOUNT_MODES,
    MountChoice,
    choose_mount,
    read_mount_file,
)
from aeromag_env.flight.mounting import Mount
from aeromag_env.flight.quality import fault_report
from aeromag_env.flight.validation import (
    PathLike,
    file_error,
    needed_fields,
    plausibility_problems,
    validate,
)

#: The Earth-field model of :mod:`aeromag_env.geo.earth`, and the package that evaluates it.
EARTH_MODEL = "IGRF-14"
EARTH_MODEL_PACKAGE = "ppigrf"

#: How messages name a flight given in memory rather than as a file.
IN_MEMORY = "flight"
#: Where a job says a warning (one line): by default :func:`aeromag_env.errors.warn`.
Warn = Callable[[str], None]


class JobWarnings:
    """A job's warnings: each kept in :attr:`lines` (the result's ``warnings``) and, with
    ``emit``, issued as an :class:`~aeromag_env.errors.AeromagWarning` as it is said.

    Parameters
    ----------
    emit : bool
        Issue each warning (a fleet's flights keep theirs for their row instead).
    """

    def __init__(self, emit: bool = True) -> None:
        self.lines: list[str] = []
        self.emit = emit

    def __call__(self, message: str) -> None:
        self.lines.append(message)
        if self.emit:
            errors.warn(message)


def load_source(
    source: PathLike | Flight, needs: tuple[str, ...]
) -> tuple[Flight, list[str], Path | None]:
    """A job's flight, its input problems (one line each) and its file (None for a flight given
    in memory, which is checked as a file would be and named ``flight`` in messages).

    ``needs`` as :func:`~aeromag_env.flight.validation.validate`'s.
    """
    if isinstance(source, Flight):
        return source, validate(source, IN_MEMORY, needs), None
    flight, problems = load_flight(source, needs=needs)
    return flight, problems, Path(source)


@dataclass(frozen=True)
class Inputs:
    """What a run uses of a flight: the channels, the flight as the model sees it (with the chosen
    altitude), and the fluxgate's mount (None when no fluxgate is used)."""

    channels: Channels
    work: Flight
    mount: MountChoice | None

    @property
    def flux_name(self) -> str:
        """The fluxgate used (a required channel of every method)."""
        assert self.channels.fluxgate is not None
        return self.channels.fluxgate.name

    @property
    def scalar_name(self) -> str | None:
        """The scalar magnetometer chosen, None when the file has no usable one."""
        return self.channels.scalar.name if self.channels.scalar else None


def parse_mount_option(text: str) -> tuple[str, dict[str, Mount] | None]:
    """``--mount`` → (mode, the file's mounts): ``auto``, ``identity`` or a JSON file."""
    if text in MOUNT_MODES:
        return text, None
    if not Path(text).is_file():
        raise AeromagError(f"--mount takes auto, identity or a JSON mount file; {text!r} is none")
    return "file", read_mount_file(text)


def choose_inputs(
    flight: Flight,
    path: PathLike,
    flux: str = "auto",
    scalar: str = "auto",
    require: tuple[str, ...] = (),
    mount: str = "auto",
    mask: np.ndarray | None = None,
    mount_matters: bool = True,
    warn: Warn = errors.warn,
    kinds: tuple[str, ...] = KINDS,
) -> Inputs:
    """Choose the channels and the fluxgate mount of a run and say their warnings to ``warn``.

    ``require`` names the channel kinds the method cannot do without (``fluxgate``, ``scalar``,
    ``altitude``), ``kinds`` those it reads at all; ``mask`` (n,) restricts the mount estimate
    (None: every sample, the mount being a constant of the installation);
    ``mount_matters=False`` (Tolles–Lawson) reports the mount without applying it. The chosen
    magnetometers get the reader's fatal unit checks (:func:`check_units`, naming ``path``), and
    their magnitude is compared with the Earth-field model
    (:func:`~aeromag_env.flight.earth_model.model_mismatch`: a warning when position, date or
    units look wrong).
    """
    mode, mounts = parse_mount_option(mount)
    channels = choose_channels(flight, flux, scalar, require, kinds)
    check_units(flight, path, channels.needs())
    work = with_altitude(flight, channels.altitude)
    choice = None
    if channels.fluxgate is not None:
        name = channels.fluxgate.name
        given = None
        if mounts is not None:
            if name not in mounts:
                raise AeromagError(
                    f"--mount {mount}: no mount for {name} (the file gives {', '.join(mounts)})"
                )
            given = mounts[name]
        choice = choose_mount(work, name, mode, given, mask, relevant=mount_matters)
    scalar_name, flux_name = (c.name if c else None for c in (channels.scalar, channels.fluxgate))
    mismatch = model_mismatch(work, scalar_name, flux_name)
    for message in (*channels.warnings, choice.warning if choice else None, mismatch):
        if message:
            warn(message)
    return Inputs(channels, work, choice)


def check_units(flight: Flight, path: PathLike, names: list[str]) -> None:
    """The reader's fatal unit checks (a field in µT…) for the channels chosen after reading."""
    needed = needed_fields(flight, names)
    for fields, fatal, message in plausibility_problems(flight):
        if fatal and needed.intersection(fields):
            raise file_error(path, message)


def provenance(
    path: PathLike | None, flight: Flight, inputs: Inputs, earth_model_used: bool
) -> dict[str, Any]:
    """The report's provenance blocks (see the module docstring).

    ``path`` is the input file (None for a flight given in memory: no hash, no format);
    ``earth_model_used``: whether the run evaluated the Earth-field model (position and date).
    """
    faults = fault_report(flight)
    spikes = faults["spikes"]
    assert isinstance(spikes, dict)
    return {
        "input_sha256": None if path is None else file_sha256(path),
        "input_format": None if path is None else input_format(path),
        "channels": inputs.channels.to_dict(),
        "mount": inputs.mount.to_dict() if inputs.mount is not None else None,
        "segments": {k: faults[k] for k in ("segments", "gap_count", "gaps")},
        "flagged_samples": {
            "spikes": sum(int(e["count"]) for e in spikes.values()),
            "by_channel": spikes,
        },
        "flight_date": flight_date(flight),
        "earth_model": earth_model_info(flight, earth_model_used),
    }


def file_sha256(path: PathLike) -> str:
    """SHA-256 of a file's bytes (hex)."""
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def input_format(path: PathLike) -> str:
    """The file's format as the reader detected it from the content (``hdf5``, ``csv``, ``xyz``,
    ``mat5``, ``mat73``)."""
    return detect_format(Path(path))


def flight_date(flight: Flight) -> dict[str, str | None]:
    """``{"iso", "source"}``: the epoch the Earth model used and where it came from."""
    try:
        date = flight.date()
    except KeyError:
        return {"iso": None, "source": "none (no 'date' attribute, no 'year'/'doy' fields)"}
    except (ValueError, OverflowError) as exc:  # unreadable, or outside IGRF-14's years
        return {"iso": None, "source": f"unusable: {exc}"}
    if "date" in flight.attrs:
        source = "file attribute 'date'"
    else:
        source = "fields 'year' and 'doy' (first sample)"
    iso = date.date().isoformat() if date.time() == date.min.time() else date.isoformat()
    return {"iso": iso, "source": source}


def earth_model_info(flight: Flight, used: bool) -> dict[str, Any]:
    """Name and version of the Earth-field model, whether the run used it, and whether the
    ``diurnal`` channel was added to it (along the main field)."""
    try:
        version: str | None = importlib.metadata.version(EARTH_MODEL_PACKAGE)
    except importlib.metadata.PackageNotFoundError:
        version = None
    return {
        "name": EARTH_MODEL,
        "package": EARTH_MODEL_PACKAGE,
        "package_version": version,
        "used": used,
        "diurnal": bool(used and "diurnal" in flight),
    }
