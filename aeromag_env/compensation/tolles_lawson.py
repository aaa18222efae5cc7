"""Batch Tolles–Lawson fit of a scalar magnetometer (the industry baseline; MagNav.jl style).

The model and its 18 terms are in :mod:`aeromag_env.simulation.tolles_lawson_terms`.
"""

from __future__ import annotations

import numpy as np

from aeromag_env.compensation.dsp import bandpass, bandpass_min_length, is_all_pass
from aeromag_env.errors import AeromagError, ConfigError
from aeromag_env.simulation.tolles_lawson_terms import N_TERMS, design_matrix
from aeromag_env.units import BT_SCALE_NT


class TollesLawson:
    """Batch Tolles–Lawson fit of a scalar magnetometer (the industry baseline; MagNav.jl style).

    An estimator with scikit-learn conventions: hyperparameters in the (keyword-only) constructor,
    :meth:`fit` returns ``self``, fitted attributes end in ``_``.

    Parameters
    ----------
    bandpass_hz : (float, float) or None
        Pass band ``(low, high)`` [Hz] applied, zero-phase, to every non-constant design column and
        to the target before the solve; MagNav's conventions for a low edge ≤ 0 (low-pass) and a
        high edge ≥ fs/2 (high-pass) hold (:func:`aeromag_env.compensation.dsp.bandpass`). None: no
        filtering.
    trim : int
        Samples dropped from each end after filtering (filter edge transients); unused when
        nothing is filtered (as in MagNav).
    ridge : float
        Ridge parameter λ ≥ 0 [-], added to the diagonal of ``AᵀA``; the design columns are
        O(1) (direction cosines, ``|B|/Bt``), so λ is on that scale (MagNav uses 0.025).
    bias : bool
        Append a constant column (MagNav's ``:bias``), making 19 coefficients.
    bt_scale_nt : float
        Scale of the induced and eddy terms [nT].

    Attributes
    ----------
    coef_ : ndarray, shape (18,) or (19,)
        Coefficients [nT] in :func:`design_matrix` column order (then the bias).
    residual_std_nt_ : float
        Standard deviation of the fit residual, in the (filtered, trimmed) fit domain [nT].
    n_samples_ : int
        Samples used in the solve (after trimming or dropping non-finite ones).
    condition_number_ : float
        2-norm condition number of the (filtered) design, without the ridge term.
    remove_mean_ : bool
        True when the fit filter removed the mean (a high-pass edge): the constant part of the
        interference is then unknowable, and :meth:`predict` returns a zero-mean correction.

    Notes
    -----
    Conventions of MagNav.jl ``create_TL_A`` / ``create_TL_coef``:

    * 18 terms: permanent (3), induced (6), eddy (9), induced and eddy scaled by
      ``|B| / 50 000 nT``; eddy terms use per-sample central differences, not divided by dt,
      so the eddy coefficients depend on the sample rate;
    * a 4-pole Butterworth 0.1–0.9 Hz band-pass run forward and backward (``filtfilt``) on the
      design columns (constant ones skipped) and on the target, then ``trim = 20`` samples cut
      from each end;
    * ridge solve ``c = (AᵀA + λI)⁻¹ Aᵀ y``; MagNav's ``create_TL_coef`` defaults to λ = 0, its
      compensation structs and notebooks use λ = 0.025. Here the solve is an ordinary least
      squares on ``[A; √λ I] c ≈ [y; 0]`` (no explicit inverse);
    * the coefficients are applied to the *unfiltered* design; MagNav's notebooks remove the
      mean of the correction, ``mag_c = mag_uc − detrend(A c, mean_only=true)``
      (:attr:`remove_mean_`).

    Non-finite samples: with a filter they raise :class:`AeromagError` (filters cannot skip
    them; cut the flight into finite parts first); without one, the rows with any non-finite
    value (in the design, which spreads a flux gap to its neighbours through the central
    difference, or in the target) are dropped.

    Runs: given ``runs`` (the continuous runs of valid samples, e.g.
    :meth:`aeromag_env.compensation.samples.Samples.runs`), :meth:`fit` builds the design (its
    eddy terms difference neighbouring samples), band-passes it and the target, and trims
    ``trim`` samples from each end *per run*, then solves on the concatenation; runs too short
    to filter and trim are left out. :meth:`predict` builds the design per run and is NaN outside
    the runs. One run spanning the whole series is the plain fit.
    """

    coef_: np.ndarray
    residual_std_nt_: float
    n_samples_: int
    condition_number_: float
    remove_mean_: bool

    def __init__(
        self,
        *,
        bandpass_hz: tuple[float, float] | None = (0.1, 0.9),
        trim: int = 20,
        ridge: float = 0.0,
        bias: bool = False,
        bt_scale_nt: float = BT_SCALE_NT,
    ) -> None:
        if bandpass_hz is not None and len(bandpass_hz) != 2:
            raise ConfigError(f"TollesLawson.bandpass_hz needs (low, high) [Hz], got {bandpass_hz}")
        if isinstance(trim, bool) or not isinstance(trim, (int, np.integer)) or trim < 0:
            raise ConfigError(f"TollesLawson.trim must be an integer ≥ 0 samples, got {trim!r}")
        if not (np.isfinite(ridge) and ridge >= 0):
            raise ConfigError(f"TollesLawson.ridge must be ≥ 0, got {ridge}")
        if not (np.isfinite(bt_scale_nt) and bt_scale_nt > 0):
            raise ConfigError(f"TollesLawson.bt_scale_nt must be > 0 nT, got {bt_scale_nt}")
        self.bandpass_hz = bandpass_hz
        self.trim = int(trim)
        self.ridge = float(ridge)
        self.bias = bool(bias)
        self.bt_scale_nt = float(bt_scale_nt)

    def fit(
        self,
        flux: np.ndarray,
        scalar: np.ndarray,
        fs_hz: float,
        earth_total: np.ndarray | None = None,
        runs: list[slice] | None = None,
    ) -> TollesLawson:
        """Fit the coefficients.

        Parameters
        ----------
        flux : ndarray, shape (n, 3)
            Vector magnetometer in body axes [nT].
        scalar : ndarray, shape (n,)
            Scalar magnetometer [nT].
        fs_hz : float
            Sample rate [Hz].
        earth_total : ndarray, shape (n,), optional
            Known ambient total field [nT] (e.g. IGRF + diurnal, or the simulator's truth);
            the target is ``scalar − earth_total`` when given, else ``scalar``.
        runs : list of slice, optional
            Runs of valid samples to fit, each prepared on its own (class notes). None: all.

        Returns
        -------
        self

        Raises
        ------
        AeromagError
            A pass band beyond the Nyquist frequency (:meth:`check_band`), or no run long
            enough to filter, trim and fit (:meth:`check_length`).
        """
        self.check_band(fs_hz)
        if self._filters(fs_hz):  # else the rows are counted below
            lengths = [len(flux)] if runs is None else [r.stop - r.start for r in runs]
            self.check_length(max(lengths, default=0), fs_hz, "a run of valid samples")
        if runs is None:
            a, y = self._prepare(*self._design_and_target(flux, scalar, earth_total), fs_hz)
        else:
            a, y = self._prepare_runs(flux, scalar, earth_total, fs_hz, runs)
        if a.shape[0] <= a.shape[1]:
            raise AeromagError(
                f"Tolles–Lawson fit needs more than {a.shape[1]} samples, got {a.shape[0]}"
            )
        self.coef_ = _ridge_solve(a, y, self.ridge)
        self.residual_std_nt_ = float(np.std(y - a @ self.coef_))
        self.n_samples_ = int(a.shape[0])
        self.condition_number_ = float(np.linalg.cond(a))
        low = self.bandpass_hz[0] if self.bandpass_hz is not None else 0.0
        self.remove_mean_ = bool(0 < low < fs_hz / 2)
        return self

    def check_band(self, fs_hz: float) -> None:
        """One-line error when the pass band does not fit a sample rate ``fs_hz`` [Hz]: an edge
        above the Nyquist frequency fs/2 (HIGH = fs/2 is MagNav's "no low-pass": a high-pass)
        or a LOW edge at or above it."""
        if self.bandpass_hz is None or not np.isfinite(fs_hz):
            return
        low, high = self.bandpass_hz
        nyquist = fs_hz / 2
        if high > nyquist * (1 + 1e-6) or low >= nyquist:  # 1e-6: a median rate's rounding
            raise ConfigError(
                f"Tolles–Lawson band-pass (--tl-bandpass) {low:g} {high:g} Hz does not fit this "
                f"flight's sample rate {fs_hz:g} Hz: use 0 ≤ LOW < HIGH ≤ {nyquist:g} Hz, the "
                "Nyquist frequency fs/2 (HIGH = fs/2: high-pass only)"
            )

    def length_needed(self, fs_hz: float) -> tuple[int, str]:
        """Fewest samples one run of valid samples needs to be fitted at ``fs_hz`` [Hz], and why.

        More than the coefficients (18, or 19 with the bias) are left after the band-pass (whose
        zero-phase padding needs :func:`aeromag_env.compensation.dsp.bandpass_min_length`
        samples) and after ``trim`` samples are cut from each end.
        """
        self.check_band(fs_hz)
        fit = N_TERMS + self.bias + 1
        if not self._filters(fs_hz):
            return fit, f"more than {fit - 1} to fit {fit - 1} coefficients"
        assert self.bandpass_hz is not None
        low, high = self.bandpass_hz
        pad = self._padding(fs_hz)
        why = (
            f"the {low:g}–{high:g} Hz band-pass needs {pad}, then trim {self.trim} at each end "
            f"(--tl-trim) and more than {fit - 1} left to fit {fit - 1} coefficients"
        )
        return max(pad, 2 * self.trim + fit), why

    def _padding(self, fs_hz: float) -> int:
        """Fewest samples the band-pass filters at ``fs_hz`` [Hz] (0 at an unknown rate)."""
        assert self.bandpass_hz is not None
        return bandpass_min_length(fs_hz, *self.bandpass_hz) if np.isfinite(fs_hz) else 0

    def _filters(self, fs_hz: float) -> bool:
        """Whether the fit band-passes (and trims) at ``fs_hz`` [Hz]."""
        band = self.bandpass_hz
        return band is not None and not (np.isfinite(fs_hz) and is_all_pass(fs_hz, *band))

    def check_length(self, n: int, fs_hz: float, what: str = "a flight") -> None:
        """One-line error when ``n`` samples (of ``what``) are fewer than :meth:`length_needed`,
        saying which ``trim`` would fit."""
        need, why = self.length_needed(fs_hz)
        if n >= need:
            return
        room = (n - N_TERMS - self.bias - 1) // 2
        fits = self._filters(fs_hz) and room >= 0 and n >= self._padding(fs_hz)  # trim = room
        raise AeromagError(
            f"Tolles–Lawson fit needs {what} of at least {need} samples ({why}); this one has "
            f"{n}" + (f"; --tl-trim ≤ {room} would fit" if fits else "")
        )

    def predict(self, flux: np.ndarray, runs: list[slice] | None = None) -> np.ndarray:
        """Scalar interference [nT], shape (n,): unfiltered design × ``coef_``.

        With ``runs``, the design is built on each run and the result is NaN outside them.
        With :attr:`remove_mean_` the mean over the finite samples is removed.
        """
        if not hasattr(self, "coef_"):
            raise AeromagError("TollesLawson is not fitted; call fit() first")
        if runs is None:
            interf = self._design(flux) @ self.coef_
        else:
            interf = np.full(len(flux), np.nan)
            for run in runs:
                interf[run] = self._design(flux[run]) @ self.coef_
        finite = np.isfinite(interf)
        if self.remove_mean_ and np.any(finite):
            interf = interf - np.mean(interf[finite])
        return interf

    def compensate(self, flux: np.ndarray, scalar: np.ndarray) -> np.ndarray:
        """Compensated scalar ``scalar − predict(flux)`` [nT], shape (n,)."""
        scalar = np.asarray(scalar, dtype=float)
        return scalar - self.predict(flux)

    def _design(self, flux: np.ndarray) -> np.ndarray:
        flux = np.asarray(flux, dtype=float)
        if flux.ndim != 2 or flux.shape[1] != 3:
            raise AeromagError(f"flux must have shape (n, 3) [nT], got {flux.shape}")
        a = design_matrix(flux, self.bt_scale_nt)
        return np.hstack([a, np.ones((a.shape[0], 1))]) if self.bias else a

    def _design_and_target(
        self, flux: np.ndarray, scalar: np.ndarray, earth_total: np.ndarray | None
    ) -> tuple[np.ndarray, np.ndarray]:
        a = self._design(flux)
        y = np.asarray(scalar, dtype=float)
        if earth_total is not None:
            y = y - np.asarray(earth_total, dtype=float)
        if y.shape != (a.shape[0],):
            raise AeromagError(
                f"scalar (and earth_total) must have shape ({a.shape[0]},) like flux, got {y.shape}"
            )
        return a, y

    def _prepare_runs(
        self,
        flux: np.ndarray,
        scalar: np.ndarray,
        earth_total: np.ndarray | None,
        fs_hz: float,
        runs: list[slice],
    ) -> tuple[np.ndarray, np.ndarray]:
        """Design and target prepared (:meth:`_prepare`) run by run, then concatenated."""
        if len(runs) == 1:  # no concatenation: the plain fit's arrays, bit for bit
            run = runs[0]
            total = None if earth_total is None else earth_total[run]
            return self._prepare(*self._design_and_target(flux[run], scalar[run], total), fs_hz)
        parts = []
        for run in runs:
            total = None if earth_total is None else earth_total[run]
            a, y = self._design_and_target(flux[run], scalar[run], total)
            if self._long_enough(a.shape[0], fs_hz):
                parts.append(self._prepare(a, y, fs_hz))
        if not parts:
            return np.empty((0, 18 + self.bias)), np.empty(0)
        return np.vstack([a for a, _ in parts]), np.concatenate([y for _, y in parts])

    def _long_enough(self, n: int, fs_hz: float) -> bool:
        """Whether a run of ``n`` samples survives the filter's padding and the trim."""
        band = self.bandpass_hz
        if band is None or is_all_pass(fs_hz, *band):
            return n > 0
        low, high = band
        return n > 2 * self.trim and n >= bandpass_min_length(fs_hz, low, high)

    def _prepare(self, a: np.ndarray, y: np.ndarray, fs_hz: float) -> tuple[np.ndarray, np.ndarray]:
        """Filter and trim (with a band), or drop non-finite rows (without one)."""
        ok = np.all(np.isfinite(a), axis=1) & np.isfinite(y)
        band = self.bandpass_hz
        if band is None or is_all_pass(fs_hz, *band):  # MagNav neither filters nor trims then
            return a[ok], y[ok]
        if not np.all(ok):
            raise AeromagError(
                f"a band-passed Tolles–Lawson fit cannot skip the {np.count_nonzero(~ok)} "
                "non-finite sample(s); cut the flight into finite parts or set bandpass_hz=None"
            )
        low, high = band
        keep = slice(self.trim, a.shape[0] - self.trim)
        return bandpass(a, fs_hz, low, high)[keep], bandpass(y, fs_hz, low, high)[keep]


def _ridge_solve(a: np.ndarray, y: np.ndarray, ridge: float) -> np.ndarray:
    """``argmin |A c − y|² + λ |c|²`` by least squares on ``[A; √λ I] c ≈ [y; 0]``."""
    if ridge > 0:
        m = a.shape[1]
        a = np.vstack([a, np.sqrt(ridge) * np.eye(m)])
        y = np.concatenate([y, np.zeros(m)])
    coef, *_ = np.linalg.lstsq(a, y, rcond=None)
    return coef
