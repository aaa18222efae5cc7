"""Which scalar, fluxgate and altitude channels to use, and why.

A real file carries several of each (SGL: ``mag_1_uc`` … ``mag_5_uc``, ``flux_a`` … ``flux_d``,
``alt``/``utm_z``/``ins_alt``/``msl``), and not all of them hold data: in the public Flt1002
``flux_a`` is all NaN. :func:`choose_channels` picks one of each kind and says why, in one short
reason per channel that ``report.json`` keeps:

* candidates are taken in the preference order of :data:`ALTITUDE_CANDIDATES` and in name order
  for the magnetometers (``mag_1_uc`` is the tail stinger in the SGL layout, ``flux_a`` the first
  fluxgate);
* a candidate is *unusable* when it is absent, has fewer than :data:`MIN_FINITE_FRACTION` finite
  samples, or an implausible magnitude (a field in µT, an altitude of 10⁵ m:
  :func:`aeromag_env.flight.validation.plausibility_problems` and :data:`ALTITUDE_RANGE_M`);
* a usable candidate is *clean* when at least :data:`CLEAN_FINITE_FRACTION` of its samples are
  finite and at most :data:`CLEAN_SPIKE_FRACTION` are flagged as spikes
  (:func:`aeromag_env.flight.quality.spike_flags`);
* the first clean candidate in preference order is used, else the usable one with the most finite
  samples and the fewest spikes. Passing over a present candidate is reported as a warning.

A name given explicitly (``--flux flux_b``) is used as given; an unknown name is a one-line
error listing the file's channels of that kind, an all-NaN one a warning.

Altitude channels that disagree by more than :data:`ALTITUDE_MARGIN_M` (median absolute
difference) are warned about: beyond the geoid's undulation (ellipsoidal vs sea-level heights
differ by up to ~100 m) one of them is wrong (feet, a barometric height), and IGRF changes by
~0.03 nT/m with height.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from aeromag_env.errors import AeromagError
from aeromag_env.flight.data import ALTITUDE_NAMES, Flight, vector_names
from aeromag_env.flight.quality import spike_flags
from aeromag_env.flight.validation import plausibility_problems

#: Altitude channels in order of preference (ellipsoidal heights first, then sea level) [m].
ALTITUDE_CANDIDATES = (*ALTITUDE_NAMES, "msl")
#: A channel with fewer finite samples than this fraction is not used [-].
MIN_FINITE_FRACTION = 0.5
#: A channel is clean with at least this finite fraction and at most this spike fraction [-].
CLEAN_FINITE_FRACTION = 0.99
CLEAN_SPIKE_FRACTION = 1e-3
#: Plausible aircraft altitude [m].
ALTITUDE_RANGE_M = (-500.0, 20_000.0)
#: Altitude channels further apart than this (median |difference|) are warned about [m].
ALTITUDE_MARGIN_M = 100.0
#: Feet per metre, to name the likely cause of a disagreement [-].
_FEET_PER_M = 3.28084

KINDS = ("fluxgate", "scalar", "altitude")


@dataclass(frozen=True)
class Channel:
    """A channel chosen for one role, and why."""

    name: str
    reason: str

    def to_dict(self) -> dict[str, str]:
        return {"name": self.name, "reason": self.reason}


@dataclass(frozen=True)
class Quality:
    """How usable one candidate channel is.

    ``finite`` is the fraction of samples finite in every axis [-]; ``median`` the median
    magnitude [nT] (altitude [m]); ``spikes`` the flagged samples; ``problem`` why it cannot be
    used at all (None if it can).
    """

    name: str
    finite: float
    median: float
    spikes: int
    problem: str | None

    @property
    def usable(self) -> bool:
        return self.problem is None and self.finite >= MIN_FINITE_FRACTION

    def is_clean(self, n: int) -> bool:
        return self.finite >= CLEAN_FINITE_FRACTION and self.spikes <= CLEAN_SPIKE_FRACTION * n

    def summary(self, unit: str) -> str:
        """``"100 % finite, median 52310 nT, no spikes"``, or why it is unusable."""
        if self.problem is not None:
            return self.problem
        if self.finite == 0.0:
            return "all non-finite"
        spikes = f"{self.spikes} spike(s)" if self.spikes else "no spikes"
        return f"{100 * self.finite:.3g} % finite, median {self.median:.0f} {unit}, {spikes}"


@dataclass(frozen=True)
class Channels:
    """The channels chosen (None where a kind is absent and not required) and the warnings."""

    fluxgate: Channel | None
    scalar: Channel | None
    altitude: Channel | None
    warnings: tuple[str, ...] = ()

    def to_dict(self) -> dict[str, dict[str, str] | None]:
        return {kind: (c.to_dict() if (c := getattr(self, kind)) else None) for kind in KINDS}

    def needs(self) -> list[str]:
        """``needs`` tokens of the chosen magnetometers (for the reader's unit checks)."""
        return [c.name for c in (self.fluxgate, self.scalar) if c is not None]


def choose_channels(
    flight: Flight,
    flux: str = "auto",
    scalar: str = "auto",
    require: tuple[str, ...] = (),
    kinds: tuple[str, ...] = KINDS,
) -> Channels:
    """Pick the fluxgate, scalar and altitude channels of ``flight``.

    Parameters
    ----------
    flight : Flight
    flux, scalar : str
        ``"auto"`` or a channel name (``flux_b``, ``mag_3_uc``) to use as given.
    require : tuple of str
        Kinds (:data:`KINDS`) the caller cannot do without: none usable is a one-line error.
    kinds : tuple of str
        Kinds to choose at all (the others are None): a caller that never reads a scalar.

    Returns
    -------
    Channels
    """
    warnings: list[str] = []
    candidates = {
        "fluxgate": _flux_candidates(flight),
        "scalar": _scalar_candidates(flight),
        "altitude": ALTITUDE_CANDIDATES,
    }
    requested = {"fluxgate": flux, "scalar": scalar, "altitude": "auto"}
    chosen = {
        kind: _choose(kind, flight, requested[kind], candidates[kind], warnings)
        if kind in kinds
        else None
        for kind in KINDS
    }
    for kind in require:
        if chosen[kind] is None:
            raise AeromagError(f"no usable {kind} channel: {_absent_text(kind, flight)}")
    if chosen["altitude"] is not None:
        warnings += altitude_disagreements(flight, chosen["altitude"].name)
    return Channels(**chosen, warnings=tuple(warnings))


def with_altitude(flight: Flight, altitude: Channel | None) -> Flight:
    """The flight as the Earth model should see it: ``alt`` holding the chosen altitude channel
    (the model reads the first of ``alt``, ``utm_z``, ``ins_alt``); the same object when that
    already is the chosen one."""
    if altitude is None or flight.altitude_name() == altitude.name:
        return flight
    return Flight({**flight.fields, "alt": flight[altitude.name]}, flight.attrs)


def channel_quality(flight: Flight, kind: str, names: list[str] | tuple[str, ...]) -> list[Quality]:
    """:class:`Quality` of each candidate of one kind, in the given order."""
    present = [nm for nm in names if _present(flight, kind, nm)]
    spikes = spike_flags(flight, present) if kind != "altitude" and present else {}
    problems = {} if kind == "altitude" else _magnetometer_problems(flight)
    out = []
    for name in names:
        if name not in present:
            out.append(Quality(name, 0.0, float("nan"), 0, "absent"))
            continue
        values = _magnitude(flight, kind, name)
        ok = np.isfinite(values)
        median = float(np.median(values[ok])) if ok.any() else float("nan")
        problem = _problem(kind, name, median, problems)
        n_spikes = int(spikes[name].sum()) if name in spikes else 0
        out.append(Quality(name, float(ok.mean()), median, n_spikes, problem))
    return out


def altitude_disagreements(flight: Flight, chosen: str) -> list[str]:
    """Warnings for the other altitude channels that disagree with ``chosen`` by more than
    :data:`ALTITUDE_MARGIN_M` (median absolute difference over samples finite in both)."""
    out = []
    for q in channel_quality(flight, "altitude", ALTITUDE_CANDIDATES):
        if q.name == chosen or q.problem == "absent":
            continue
        a, b = flight[chosen], flight[q.name]
        ok = np.isfinite(a) & np.isfinite(b)
        if not ok.any():
            continue
        diff = float(np.median(np.abs(a[ok] - b[ok])))
        if diff > ALTITUDE_MARGIN_M:
            hint = _feet_hint(a[ok], b[ok], chosen, q.name)
            out.append(
                f"altitude channels disagree: {chosen} and {q.name} differ by a median "
                f"{diff:.0f} m (> {ALTITUDE_MARGIN_M:.0f} m){hint}; "
                f"using {chosen} (IGRF changes by ~0.03 nT/m with height)"
            )
    return out


def _choose(
    kind: str, flight: Flight, requested: str, candidates: tuple[str, ...], warnings: list[str]
) -> Channel | None:
    """One kind: the requested channel, else the first clean or best usable candidate."""
    unit = "m" if kind == "altitude" else "nT"
    if requested != "auto":
        return _requested(kind, flight, requested, candidates, warnings)
    qualities = channel_quality(flight, kind, candidates)
    usable = [q for q in qualities if q.usable]
    if not usable:
        return None
    clean = [q for q in usable if q.is_clean(flight.n)]
    best = clean[0] if clean else max(usable, key=lambda q: (q.finite, -q.spikes))
    passed = [q for q in qualities[: qualities.index(best)] if q.problem != "absent"]
    order = "preference" if kind == "altitude" else "name"
    rule = f"first clean {kind} in {order} order" if clean else "none clean; most complete"
    reason = f"{rule} ({best.summary(unit)})"
    if passed:
        skipped = "; ".join(f"{q.name}: {q.summary(unit)}" for q in passed)
        reason += f"; passed over {skipped}"
        warnings.append(f"{kind}: using {best.name}, not {passed[0].name} ({skipped})")
    return Channel(best.name, reason)


def _requested(
    kind: str, flight: Flight, name: str, candidates: tuple[str, ...], warnings: list[str]
) -> Channel:
    """A channel named by the user: used as given; absent → error, empty → warning."""
    if not _present(flight, kind, name, explicit=True):
        shown = ", ".join(nm for nm in candidates if _present(flight, kind, nm)) or "none"
        columns = f" ({name}_x/y/z)" if kind == "fluxgate" else ""
        raise AeromagError(
            f"--{'flux' if kind == 'fluxgate' else kind} {name}: no {kind} {name}{columns} in the "
            f"file; {kind}s present: {shown}"
        )
    (q,) = channel_quality(flight, kind, [name])
    if q.finite == 0.0:
        others = [c.name for c in channel_quality(flight, kind, candidates) if c.usable]
        warnings.append(
            f"{kind} {name} is all non-finite: nothing to compensate with it "
            f"(usable {kind}s: {', '.join(others) or 'none'})"
        )
    return Channel(name, f"given on the command line ({q.summary('nT')})")


def _flux_candidates(flight: Flight) -> tuple[str, ...]:
    return tuple(flight.fluxgates())


def _scalar_candidates(flight: Flight) -> tuple[str, ...]:
    """``mag_N_uc`` in numeric order of N (``mag_2_uc`` before ``mag_10_uc``)."""
    return tuple(sorted(flight.scalars(), key=lambda nm: int(nm.split("_")[1])))


def _present(flight: Flight, kind: str, name: str, explicit: bool = False) -> bool:
    if kind == "fluxgate":
        return all(nm in flight for nm in vector_names(name))
    return name in flight if (explicit or kind != "scalar") else name in flight.scalars()


def _magnitude(flight: Flight, kind: str, name: str) -> np.ndarray:
    """|B| of a fluxgate [nT], else the channel itself."""
    if kind == "fluxgate":
        with np.errstate(over="ignore", invalid="ignore"):
            return np.linalg.norm(flight.vector(name), axis=1)
    return flight[name]


def _problem(
    kind: str, name: str, median: float, problems: dict[tuple[str, ...], str]
) -> str | None:
    """Why a present channel cannot be used (implausible magnitude), or None."""
    if kind == "altitude":
        low, high = ALTITUDE_RANGE_M
        ok = not np.isfinite(median) or low <= median <= high
        return None if ok else f"median {median:.4g} m is not an aircraft altitude"
    fields = vector_names(name) if kind == "fluxgate" else (name,)
    return problems.get(tuple(fields))


def _feet_hint(a: np.ndarray, b: np.ndarray, name_a: str, name_b: str) -> str:
    """`` ({name} looks like feet)`` when one channel is ~3.28 times the other."""
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = float(np.nanmedian(b / a))
    for value, name in ((ratio, name_b), (1.0 / ratio if ratio else 0.0, name_a)):
        if abs(value - _FEET_PER_M) < 0.05 * _FEET_PER_M:
            return f" ({name} looks like feet)"
    return ""


def _absent_text(kind: str, flight: Flight) -> str:
    """What the file has of one kind, with why each is unusable."""
    candidates = {
        "fluxgate": _flux_candidates(flight),
        "scalar": _scalar_candidates(flight),
        "altitude": ALTITUDE_CANDIDATES,
    }[kind]
    qualities = [q for q in channel_quality(flight, kind, candidates) if q.problem != "absent"]
    if not qualities:
        looked = {"fluxgate": "flux_a_x/y/z, flux_b_x/y/z…", "scalar": "mag_1_uc, mag_2_uc…"}
        return f"none in the file (looked for {looked.get(kind, ', '.join(ALTITUDE_CANDIDATES))})"
    unit = "m" if kind == "altitude" else "nT"
    return "; ".join(f"{q.name}: {q.summary(unit)}" for q in qualities)


def _magnetometer_problems(flight: Flight) -> dict[tuple[str, ...], str]:
    """Implausible-magnitude messages of the fluxgates and scalars, by their field names."""
    return {fields: msg for fields, _, msg in plausibility_problems(flight)}
