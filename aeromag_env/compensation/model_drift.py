"""Does a calibrated model still fit this flight? The evidence behind "recalibrate".

A model fitted on one aircraft's calibration flight fits that aircraft's other flights as long
as the aircraft is unchanged. Applied to another aircraft, or to the same one after maintenance
(a shifted permanent field), it leaves the interference it no longer describes in the output.
:func:`drift_evidence` measures that against the calibration's own figures (stored in the model
at calibration, :func:`calibration_residual`):

* ``tl``: the compensated field's spread in MagNav's 0.1–0.9 Hz band (where the aircraft's
  manoeuvre-driven field lives) and the share of it that the 18 Tolles–Lawson terms explain
  when refitted on this flight (a refit that explains much means aircraft field is left; the
  ground at survey altitude, which the terms cannot follow, explains little);
* the Kalman family: the same two figures of the fluxgate's residual after the calibrated
  coefficients, ``T_m − T − H x_cal``, taken along the field (what a total-field sensor would
  see of it), with the filter's adaptation left out (it would absorb the change). Its size alone
  would not do: the ground's vector field is tens of nT at survey altitude, as large as a
  maintenance shift, but the aircraft's terms do not explain it.

A flight fails the check (:func:`drift_warning`) when its band-passed residual is more than
:data:`RESIDUAL_RATIO` times the calibration's and above :data:`RESIDUAL_FLOOR_NT`, and the
refit explains more than :data:`EXPLAINED_FRACTION` of it.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from aeromag_env.compensation.dsp import bandpass_finite, bandpass_min_length
from aeromag_env.compensation.model import interference_from_states
from aeromag_env.compensation.tolles_lawson import TollesLawson
from aeromag_env.errors import AeromagError

#: The band of the ``tl`` residual [Hz] (MagNav.jl's compensation band).
BAND_HZ = (0.1, 0.9)
#: A band-passed residual this many times the calibration's fails the check, per kind of model
#: [-]. Measured on simulated pairs (experiments/calibrate_then_apply.py, six aircraft): the same
#: aircraft's surveys stay below the calibration's (the box has the strongest manoeuvres; ``tl``
#: 0.44–0.52×, the filters 0.93–1.0×), and over 50 nT of crustal geology ``tl`` reaches 3.4×
#: (the ground, which the refit does not explain, 34 % at most) and the filters 1.0× (their
#: calibrated state's own in-band error, 0.4 nT, dominates); a permanent-field shift of
#: (60, −40, 30) nT reaches 19–22× (``tl``) and 1.9–2.1× (the filters), another aircraft 33–117×
#: and 3.5–8.4×, all explained by the refit.
RESIDUAL_RATIO = {"tl": 3.0, "filter": 1.4}
#: …and above this floor [nT] (a residual at the sensor noise never fails).
RESIDUAL_FLOOR_NT = 0.05
#: ``tl``: …and the refitted terms explain more than this share of its variance [-].
EXPLAINED_FRACTION = 0.5


def tl_residual(
    compensated: np.ndarray, flux: np.ndarray, fs_hz: float, parts: list[slice]
) -> dict[str, Any]:
    """Band-passed spread of a ``tl``-compensated field and the share the TL terms explain.

    Parameters
    ----------
    compensated : (n,) the compensated scalar [nT] (NaN where flagged)
    flux : (n, 3) the fluxgate [nT]
    fs_hz : the sample rate [Hz]
    parts : the continuous segments

    Returns
    -------
    dict
        ``band_std_nt`` [nT], ``explained_fraction`` [-] (None when no run is long enough to
        refit), ``samples``.
    """
    band = bandpass_finite(compensated, fs_hz, *BAND_HZ, segments=parts)
    ok = np.isfinite(band)
    std = float(np.std(band[ok])) if ok.any() else None
    explained = None
    if std is not None and std > 0:
        explained = _explained(compensated, flux, fs_hz, parts, std)
    return {"band_std_nt": std, "explained_fraction": explained, "samples": int(ok.sum())}


def _explained(
    compensated: np.ndarray, flux: np.ndarray, fs_hz: float, parts: list[slice], std: float
) -> float | None:
    """Share of the band-passed variance of ``compensated`` a TL refit explains [-]."""
    ok = np.isfinite(compensated) & np.all(np.isfinite(flux), axis=1)
    runs = [r for r in _runs(ok, parts) if r.stop - r.start >= bandpass_min_length(fs_hz, *BAND_HZ)]
    refit = TollesLawson(bandpass_hz=BAND_HZ, trim=20, ridge=0.0)
    try:
        refit.fit(flux, compensated, fs_hz, runs=runs)
    except AeromagError:
        return None
    return float(max(0.0, 1.0 - (refit.residual_std_nt_ / std) ** 2))


def _runs(ok: np.ndarray, parts: list[slice]) -> list[slice]:
    from aeromag_env.flight.quality import runs

    return runs(ok, parts)


def vector_residual(
    x_cal: np.ndarray,
    y: np.ndarray,
    t_b: np.ndarray,
    tdot_b: np.ndarray,
    flux: np.ndarray,
    fs_hz: float,
    parts: list[slice],
) -> dict[str, Any]:
    """The fluxgate's residual after the calibrated coefficients ``x_cal`` (21,), along the
    field, as :func:`tl_residual` figures it; and its RMS over the axes.

    Parameters
    ----------
    x_cal : (21,) the calibrated state [physical units]
    y : (n, 3) ``T_m − T`` [nT] (NaN where flagged)
    t_b, tdot_b : (n, 3) the model field in body axes [nT] and its rate [nT/s]
    flux : (n, 3) the fluxgate in body axes [nT] (the refit's terms)
    fs_hz : the sample rate [Hz]
    parts : the continuous segments

    Returns
    -------
    dict
        :func:`tl_residual`'s ``band_std_nt``, ``explained_fraction``, ``samples`` of the
        residual along the field, and ``residual_rms_nt`` [nT] of the vector residual.
    """
    r = y - interference_from_states(x_cal, t_b, tdot_b)
    unit = t_b / np.linalg.norm(t_b, axis=1, keepdims=True)
    along = np.sum(r * unit, axis=1)
    ok = np.all(np.isfinite(r), axis=1)
    rms = float(np.sqrt(np.mean(np.sum(r[ok] ** 2, axis=1)))) if ok.any() else None
    return {**tl_residual(along, flux, fs_hz, parts), "residual_rms_nt": rms}


def drift_warning(
    method: str, calibration: dict[str, Any], flight: dict[str, Any], what: str = "this flight"
) -> str | None:
    """A one-line "recalibrate" warning naming the evidence, or None when the model fits.

    ``calibration`` and ``flight`` are the residual figures of :func:`tl_residual` (``tl``) or
    :func:`vector_residual` (the filters) on the calibration flight and on this one.
    """
    cal, now = calibration.get("band_std_nt"), flight.get("band_std_nt")
    if cal is None or now is None:
        return None
    ratio = now / cal if cal > 0 else np.inf
    limit = RESIDUAL_RATIO["tl" if method == "tl" else "filter"]
    share = flight.get("explained_fraction")
    if not (ratio > limit and now > RESIDUAL_FLOOR_NT) or share is None:
        return None
    if share <= EXPLAINED_FRACTION:
        return None
    name = "compensated field" if method == "tl" else "fluxgate's residual along the field"
    evidence = (
        f"the {name} spreads {now:.3g} nT in the 0.1–0.9 Hz band against {cal:.3g} nT at "
        f"calibration ({ratio:.3g}×), {100 * share:.0f} % of it explained by refitting the "
        "Tolles–Lawson terms"
    )
    return (
        f"the calibrated {method} model no longer fits {what}: {evidence}; the aircraft or its "
        "installation has changed (or this is another aircraft): recalibrate (aeromag calibrate)"
    )
