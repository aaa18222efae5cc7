"""Discrepancy workflow: find where a measured flight and the model disagree, name the missing
effect, add it, and show the gap shrink on data the fit never saw (DESIGN.md, "Discrepancy
workflow").

This module runs the steps in order (:func:`discover`); each step's decisions live in its own
module of :mod:`aeromag_env.discovery`:

1. **Base model** (:mod:`~aeromag_env.discovery.preparation`,
   :mod:`~aeromag_env.discovery.base_model`). The model Earth field ``T`` (IGRF-14 along the
   track, rotated by the file's attitude, plus ``diurnal`` along the main field when the file has
   a base-station channel) and the 21 coefficients of paper eq. 5, fitted on the calibration
   part. The simulated fluxgate signal is ``T + T_p + A T + B Ṫ``; the residual is measured
   minus simulated.
2. **Noise model** (:mod:`~aeromag_env.discovery.noise_model`,
   :mod:`~aeromag_env.discovery.whitened_problem`). Per axis, white noise plus a first-order
   Gauss–Markov process (the fluxgate's coloured noise), fitted by maximum likelihood to the
   residual. Its Kalman innovations whiten the residual and every regressor (generalised least
   squares), so tests are not fooled by coloured noise — a naive F-test on the raw residual
   would be.
3. **Candidates** (:mod:`~aeromag_env.discovery.candidates`). Every effect of
   :mod:`aeromag_env.simulation.effects` builds its regressor groups from the channels present
   (one group per auxiliary channel for ``onboard_current``). A group whose part outside the
   base regressors' span is below
   :data:`~aeromag_env.discovery.candidates.ABSORBED_FRACTION` of its variance is *absorbed*
   (Frisch–Waugh–Lovell) and never tested or named; effects marked ``absorbed_by`` in the
   library (offset, scale, non-orthogonality, misalignment) are always such groups.
4. **Forward selection** (:mod:`~aeromag_env.discovery.evidence`,
   :mod:`~aeromag_env.discovery.selection`). Each remaining group gets a partial F-test on the
   whitened problem; a group has evidence when it passes Holm's correction (``p < α / m`` with m
   groups left) *and* its ΔBIC is positive (:func:`~aeromag_env.discovery.evidence.significant`).
   The F-test alone keeps a fixed false-inclusion rate per flight (about α) and trusts the fitted
   noise model, whose slow part a 20-min calibration under-states; the BIC penalty, ``log(rows)``
   per regressor, grows with the data and asks a 3-regressor group for F > 10 rather than F > 6. A
   slow group with some evidence (p < 0.01), passing or not, is re-tested with the noise model
   fitted jointly with it (:mod:`~aeromag_env.discovery.joint`: a likelihood-ratio test: Holm and 6
   per degree of freedom): a slow effect is not written off as slow noise. The strongest group by
   p-value enters, and the search repeats until none has evidence. Groups that differ only in a
   non-linear parameter (the eddy time constant, the lag) are profiled: the best grid value
   competes with one more degree of freedom, and is refined between its grid neighbours once it
   enters. After each entry the noise model is re-fitted; its coloured part may shrink only where
   the entered group cannot have absorbed it (:func:`~aeromag_env.discovery.noise_model.ratchet`).
   A chosen ``sensor_lag`` shifts the whole modelled signal — Earth field, base aircraft field and
   the other named additive effects — not the Earth field alone
   (:func:`~aeromag_env.discovery.selection.lag_on_signal`): a lag also delays the aircraft's eddy
   field, ``−τ B T̈``, which is exactly the signature of ``eddy_time_constant``; with the Earth
   field alone shifted, that remainder let ``eddy_time_constant`` follow a true lag. A backward
   pass then drops any named effect without evidence (same rule, Holm over the named ones) given
   all the others.
5. **Gap** (:mod:`~aeromag_env.discovery.gap`). Base and augmented models predict the held-out
   part; the gap is the RMS of measured minus simulated there above the white-noise floor,
   ``sqrt(RMS² − σ_w²)`` with ``σ_w`` from the final noise model (the sensor's white noise is no
   model gap; the raw RMS is reported too).
6. **Report** (:mod:`~aeromag_env.discovery.diagnostics`, :mod:`~aeromag_env.discovery.report`,
   :mod:`~aeromag_env.discovery.augmented_model`): where the base model and the data disagree,
   the named effects and every candidate's verdict, and the augmented model as a simulator
   configuration.

With ``ground="separate"`` (survey lines over magnetic ground), each run of calibration or
held-out samples is first projected off the ground's span
(:mod:`~aeromag_env.discovery.ground`): navigation-frame splines rotated by the attitude, knots
a fraction of the clearance apart. The measured series and every regressor lose that part, so
every step above sees only what the ground cannot explain; candidates the ground takes (almost)
entirely are absorbed by it and listed in a caveat.

The held-out part is, by default, every third 60-s block (interleaved: a slowly varying field is
interpolated, not extrapolated); with ``calibration_window`` it is everything outside that window.
Gaps in time (a step over 1.5× the median interval) split the flight: samples within
:data:`~aeromag_env.discovery.preparation.GAP_GUARD_SAMPLES` of a gap are dropped (their
derivatives straddle it) and the noise model bridges it (the FOGM state is propagated over the
missing time, as over held-out blocks). Non-finite samples are dropped and counted.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from aeromag_env.discovery.augmented_model import model_config
from aeromag_env.discovery.base_model import BaseSpan, base_columns, base_state
from aeromag_env.discovery.candidates import candidate_groups
from aeromag_env.discovery.diagnostics import diagnostics
from aeromag_env.discovery.evidence import ALPHA
from aeromag_env.discovery.gap import held_out_gap
from aeromag_env.discovery.ground import GROUND_MODES, as_fitted, base_off_ground
from aeromag_env.discovery.preparation import prepare
from aeromag_env.discovery.report import build_report, missing_effects
from aeromag_env.discovery.selection import select_effects
from aeromag_env.errors import AeromagError
from aeromag_env.flight.data import Flight
from aeromag_env.simulation.effects import EffectContext, Group


@dataclass
class Discovery:
    """Result of :func:`discover`: the report (JSON-ready), the augmented model and series.

    Attributes
    ----------
    report : dict
        The JSON-ready report (:func:`~aeromag_env.discovery.report.build_report`).
    model : SimulationConfig
        The augmented model as a simulator configuration.
    series : dict of numpy.ndarray
        ``tt``, ``residual_before``, ``residual_after`` (n, 3; NaN where not usable) and the
        ``held_out`` mask.
    drivers : list of tuple
        Per named effect: its name, its driving channel's name and samples (n,).
    """

    report: dict[str, Any]
    model: Any  # SimulationConfig
    series: dict[str, np.ndarray] = field(default_factory=dict)
    drivers: list[tuple[str, str, np.ndarray]] = field(default_factory=list)


def discover(
    flight: Flight,
    *,
    flux: str = "flux_a",
    calibration_window: tuple[float, float] | None = None,
    alpha: float = ALPHA,
    progress: Callable[[str], None] | None = None,
    ground: str = "ignore",
) -> Discovery:
    """Run the discrepancy workflow on one flight (real or simulated; ``truth_*`` is never read).

    Parameters
    ----------
    flight, flux
        The flight and its vector magnetometer.
    calibration_window : tuple of float or None
        ``(T0, T1)`` [s] to fit on, scoring the rest; None: every third 60-s block held out.
    alpha : float
        Family-wise false-alarm level of the effect tests, in (0, 1).
    progress : callable or None
        Called with a short message at each stage.
    ground : str
        ``ignore``, or ``separate``: fit, test and score only what the magnetic ground cannot
        explain (:mod:`~aeromag_env.discovery.ground`), for survey lines over geology.

    Returns
    -------
    Discovery
        ``report`` has ``missing_effects`` (name, channel, evidence, parameters), ``gap``
        (held-out RMS before/after), ``candidates`` (every group's verdict), ``skipped``,
        ``diagnostics`` and ``data``; ``model`` is the augmented model as a
        :class:`~aeromag_env.simulation.config.SimulationConfig`.

    Raises
    ------
    AeromagError
        ``alpha`` outside (0, 1), ``ground`` not one of :data:`GROUND_MODES`, or a flight the
        workflow cannot use (:func:`.prepare`).
    """
    if not 0 < alpha < 1:
        raise AeromagError(f"alpha must be in (0, 1), got {alpha}")
    if ground not in GROUND_MODES:
        raise AeromagError(f"ground must be one of {', '.join(GROUND_MODES)}, got {ground!r}")
    from threadpoolctl import threadpool_limits

    # tall, thin products and SVDs: a second BLAS thread gains nothing on a quiet machine and
    # made every run 3-5x slower on a busy one (measured on 2 cores)
    with threadpool_limits(limits=1, user_api="blas"):
        say = progress or (lambda _m: None)
        return _discover(flight, flux, calibration_window, alpha, say, ground == "separate")


def _discover(
    flight: Flight,
    flux: str,
    calibration_window: tuple[float, float] | None,
    alpha: float,
    say: Callable[[str], None],
    ground: bool,
) -> Discovery:
    """:func:`discover` after its argument checks."""
    say("model field")
    data = prepare(flight, flux, calibration_window, ground)
    ctx = data.ctx
    base = base_columns(ctx.t_b, ctx.tdot_b)
    if data.ground is not None:
        base = base_off_ground(data.ground, base)
    span = BaseSpan(base, data.calibration)
    cands = candidate_groups(ctx, span, data.ground)
    say("noise model")
    sel = select_effects(data, base, cands.groups, cands.fractions, alpha, say)
    say("gap")
    gap, res_before, res_after = held_out_gap(data, base, cands.groups, sel)
    missing = missing_effects(data, cands.groups, sel, base)
    state = base_state(as_fitted(sel.beta, data.ground))
    model = model_config(flight, flux, state, sel.noise_after, missing)
    diag = diagnostics(
        data, span, res_before, sel.noise_before, sel.noise_after, sel.lb_before, sel.lb_after
    )
    report = build_report(flight, flux, alpha, data, cands, sel, missing, gap, diag)
    series = {
        "tt": ctx.tt,
        "residual_before": res_before,
        "residual_after": res_after,
        "held_out": data.held_out,
    }
    drivers = [_driver(ctx, cands.groups[j - 1]) for j in sel.chosen[1:]]
    return Discovery(report=report, model=model, series=series, drivers=drivers)


def _driver(ctx: EffectContext, group: Group) -> tuple[str, str, np.ndarray]:
    """A named effect, what drives it and that channel's samples (n,): its auxiliary channel (a
    current, a temperature), the altitude for ``altitude_gradient``, else time."""
    if group.channel is not None and group.channel in ctx.aux:
        return group.effect, group.channel, ctx.aux[group.channel]
    if group.effect == "altitude_gradient":
        return group.effect, "altitude [m]", ctx.alt
    return group.effect, "time [s]", ctx.tt
