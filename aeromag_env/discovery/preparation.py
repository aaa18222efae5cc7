"""Data preparation: the model Earth field along the flight and which samples are used for what.

Decides the measured-minus-model-Earth-field series the workflow fits (the model Earth field
``T``: IGRF-14 along the track, rotated by the file's attitude), which samples are usable
(non-finite samples and samples next to a time gap are dropped), and the split into the
calibration part the models are fitted on and the held-out part the gap is scored on. Samples
where the model field is unknown (non-finite attitude or position) are filled by interpolation
for the regressors only and, with the :data:`GAP_GUARD_SAMPLES` next to them (their derivatives
reach them), left out; fluxgate spikes are left out too
(:func:`aeromag_env.compensation.samples.flight_samples`). Input
the workflow cannot use (no attitude, no fluxgate, no position or date, too little calibration
or held-out data) is a one-line :class:`~aeromag_env.errors.AeromagError`.

The held-out part is, by default, every third :data:`BLOCK_S` block (interleaved: a slowly
varying field is interpolated, not extrapolated); with ``calibration_window`` it is everything
outside that window. Gaps in time (a step over 1.5× the median interval) split the flight:
samples within :data:`GAP_GUARD_SAMPLES` of a gap are dropped (their derivatives straddle it).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from aeromag_env.compensation.samples import flight_samples
from aeromag_env.discovery.base_model import base_columns
from aeromag_env.discovery.ground import GroundReference, ground_reference
from aeromag_env.errors import AeromagError
from aeromag_env.flight.data import ATTITUDE_NAMES, Flight, vector_names
from aeromag_env.simulation.effects import EffectContext

#: Length of the interleaved blocks [s]; every third block is held out.
BLOCK_S = 60.0
#: Minimum calibration data [s].
MIN_CALIBRATION_S = 300.0
#: Minimum held-out data [s].
MIN_HELD_OUT_S = 60.0
#: Samples dropped on each side of a time gap.
GAP_GUARD_SAMPLES = 2


@dataclass
class PreparedFlight:
    """A flight ready for the workflow: model field context, residual series and sample masks.

    Attributes
    ----------
    ctx : EffectContext
        Time, attitude, model Earth field in body axes and its derivatives, altitude and
        auxiliary channels: what the effects library builds its regressors from.
    y : numpy.ndarray
        Measured minus model Earth field (n, 3) [nT].
    usable, calibration, held_out : numpy.ndarray
        Boolean masks (n,): usable samples, and the calibration and held-out parts of them.
    dt : float
        Median sample interval [s].
    scheme : str
        How the held-out part was chosen, for the report.
    n_gaps : int
        Time gaps found.
    n_nonfinite : int
        Samples dropped for non-finite values.
    ground : GroundReference or None
        With ground separation, the ground's span: ``y`` is already off it, and every regressor
        must be (:meth:`GroundReference.remove`, :meth:`GroundReference.group`).
    """

    ctx: EffectContext
    y: np.ndarray  # (n, 3) measured minus model Earth field
    usable: np.ndarray
    calibration: np.ndarray
    held_out: np.ndarray
    dt: float
    scheme: str
    n_gaps: int
    n_nonfinite: int
    ground: GroundReference | None = None


def prepare(
    flight: Flight,
    flux: str,
    calibration_window: tuple[float, float] | None,
    ground: bool = False,
) -> PreparedFlight:
    """Model Earth field, usable samples and the calibration/held-out split of a flight.

    Parameters
    ----------
    flight : Flight
        The flight (``truth_*`` fields are never read).
    flux : str
        The vector magnetometer, e.g. ``"flux_a"``.
    calibration_window : tuple of float or None
        ``(T0, T1)`` [s] to fit on that window and hold out the rest; None for interleaved
        blocks.
    ground : bool
        Separate the magnetic ground (:mod:`~aeromag_env.discovery.ground`): ``y`` is taken
        off its span, run by run.

    Returns
    -------
    PreparedFlight
        The context, the measured-minus-model series and the sample masks.

    Raises
    ------
    AeromagError
        Missing attitude, fluxgate, position or date; under 10 samples; a bad window; too
        little calibration or held-out data.
    """
    _check_channels(flight, flux)
    t_n = _earth_field_ned(flight)
    tt = flight.tt
    if flight.n < 10:
        raise AeromagError(f"the flight has only {flight.n} samples")
    step = np.diff(tt)
    dt = float(np.median(step))
    gap_after = np.flatnonzero(step > 1.5 * dt)  # a gap between sample k and k + 1
    c_nb, t_b, tdot, t2dot, unknown = _body_field(flight, tt, t_n)
    alt_name = flight.altitude_name()
    alt = flight[alt_name] if alt_name else np.full(flight.n, np.nan)
    y = flight.vector(flux) - t_b
    usable = np.all(np.isfinite(y) & np.isfinite(tdot) & np.isfinite(t2dot), axis=1) & ~unknown
    n_nonfinite = int(np.sum(~usable))
    usable &= flight_samples(flight, [flux], [flux]).valid  # fluxgate spikes
    _drop_gap_neighbours(usable, gap_after)
    calibration, scheme = _calibration_part(tt, usable, calibration_window)
    held_out = usable & ~calibration
    _check_amounts(calibration, held_out, dt)
    aux = {nm: np.nan_to_num(flight[nm]) for nm in flight.aux_channels()}
    ctx = EffectContext(tt=tt, c_nb=c_nb, t_b=t_b, tdot_b=tdot, t2dot_b=t2dot, alt=alt, aux=aux)
    ref = None
    if ground:
        ref = ground_reference(flight, c_nb, y, base_columns(t_b, tdot), usable, calibration)
        y = _off_ground(ref, y, (usable, calibration, held_out), dt)
    return PreparedFlight(
        ctx, y, usable, calibration, held_out, dt, scheme, int(gap_after.size), n_nonfinite, ref
    )


def _off_ground(
    ref: GroundReference, y: np.ndarray, masks: tuple[np.ndarray, ...], dt: float
) -> np.ndarray:
    """``y`` off the ground; the samples of runs too short for it leave the masks (in place),
    which are checked again."""
    for idx in ref.dropped:
        for mask in masks:
            mask[idx] = False
    _check_amounts(masks[1], masks[2], dt)
    return ref.remove(y)


def _check_channels(flight: Flight, flux: str) -> None:
    """One-line error when the attitude or the fluxgate is missing (the attitude first)."""
    missing = [nm for nm in (*vector_names(flux), *ATTITUDE_NAMES) if nm not in flight]
    if any(nm in missing for nm in ATTITUDE_NAMES):
        raise AeromagError(
            "discovery needs the attitude (ins_roll, ins_pitch, ins_yaw) to rotate the Earth "
            "field into body axes; the file lacks "
            + ", ".join(nm for nm in missing if nm.startswith("ins_"))
        )
    if missing:
        have = ", ".join(flight.fluxgates()) or "none"
        raise AeromagError(f"no fluxgate {flux} in the file (fluxgates present: {have})")


def _earth_field_ned(flight: Flight) -> np.ndarray:
    """The model Earth field in NED (n, 3) [nT]; a one-line error without position or date."""
    from aeromag_env.compensation.compensate import earth_model_ned

    try:
        return earth_model_ned(flight)
    except KeyError as e:
        raise AeromagError(
            f"discovery needs position and date for the Earth field: {e.args[0]}"
        ) from None


def _body_field(
    flight: Flight, tt: np.ndarray, t_n: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Attitude DCM, the model Earth field in body axes with its first two derivatives, and the
    (n,) mask of samples where that field is unknown or its derivatives reach an unknown one.

    Unknown samples (non-finite attitude or position) are filled by linear interpolation in
    time, so that every regressor is finite; they are never used.
    """
    from aeromag_env.geo.frames import dcm_from_euler, nav_to_body, time_derivative

    c_nb = dcm_from_euler(*flight.attitude_rad())
    t_b = nav_to_body(c_nb, t_n)
    unknown = ~np.all(np.isfinite(t_b), axis=1)
    if unknown.any():
        c_nb = _filled(c_nb, tt, ~np.all(np.isfinite(c_nb), axis=(1, 2)))
        t_b = _filled(t_b, tt, unknown)
        near = np.convolve(unknown, np.ones(2 * GAP_GUARD_SAMPLES + 1), mode="same")
        unknown = near > 0
    tdot = time_derivative(t_b, tt, "central")
    t2dot = time_derivative(tdot, tt, "central")
    return c_nb, t_b, tdot, t2dot, unknown


def _filled(x: np.ndarray, tt: np.ndarray, bad: np.ndarray) -> np.ndarray:
    """``x`` (n, ...) with the rows ``bad`` interpolated linearly in time from the others."""
    if np.count_nonzero(~bad) < 2:
        raise AeromagError("discovery needs finite attitude and position on at least 2 samples")
    flat = x.reshape(len(x), -1).copy()
    for j in range(flat.shape[1]):
        flat[bad, j] = np.interp(tt[bad], tt[~bad], flat[~bad, j])
    return flat.reshape(x.shape)


def _drop_gap_neighbours(usable: np.ndarray, gap_after: np.ndarray) -> None:
    """Mark the samples within :data:`GAP_GUARD_SAMPLES` of a time gap, and of either end of the
    flight, unusable (in place)."""
    for g in gap_after:
        usable[max(0, g - GAP_GUARD_SAMPLES + 1) : g + 1 + GAP_GUARD_SAMPLES] = False
    usable[:GAP_GUARD_SAMPLES] = usable[-GAP_GUARD_SAMPLES:] = False


def _calibration_part(
    tt: np.ndarray, usable: np.ndarray, calibration_window: tuple[float, float] | None
) -> tuple[np.ndarray, str]:
    """The calibration mask and a description of the held-out scheme."""
    if calibration_window is None:
        block = np.floor((tt - tt[0]) / BLOCK_S).astype(int)
        calibration = usable & (block % 3 != 2)
        scheme = f"interleaved {BLOCK_S:g} s blocks: every third block held out"
    else:
        t0, t1 = calibration_window
        if not (t0 < t1):
            raise AeromagError(f"--calibration-window needs T0 < T1 [s], got {t0} {t1}")
        calibration = usable & (tt >= t0) & (tt <= t1)
        scheme = f"calibration window {t0:g}–{t1:g} s; held out: the rest of the flight"
    return calibration, scheme


def _check_amounts(calibration: np.ndarray, held_out: np.ndarray, dt: float) -> None:
    """One-line error when the calibration or the held-out part is too short."""
    cal_s, held_s = calibration.sum() * dt, held_out.sum() * dt
    if cal_s < MIN_CALIBRATION_S:
        raise AeromagError(
            f"the calibration part has {cal_s:.0f} s of usable data; discovery needs at least "
            f"{MIN_CALIBRATION_S:.0f} s (21 base coefficients per axis; slow effects need minutes)"
        )
    if held_s < MIN_HELD_OUT_S:
        raise AeromagError(
            f"only {held_s:.0f} s of usable data lie outside the calibration part; the gap is "
            f"scored on held-out data and needs at least {MIN_HELD_OUT_S:.0f} s"
        )
