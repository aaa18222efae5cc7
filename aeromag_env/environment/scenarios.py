"""Named scenarios of the tuning environment: one seed → one episode's signals and initial tuning.

=========================== ================================================================
scenario                    what varies and what the tuner must do
=========================== ================================================================
``paper``                   the paper's §4: 20 nT white noise per axis, ``R(0) = 2e-3 nT²``,
                            ``Q(0) = 1e-3 I`` (normalised); one calibration box — R must rise
                            by five decades and Q fall
``nominal``                 realistic installation (1 nT white + 1 nT FOGM), the package's
                            well-tuned filter defaults; one calibration box. The control: no
                            headroom by design (a tuner must not make it worse)
``misspecified``            1200 s of boxes; the permanent field drifts with the airframe's
                            temperature (a random walk of ``10^U(−1, 0)`` nT per sample: a
                            strong drift, 11–110 nT RMS over the flight); white sensor noise of
                            ``10^U(0, 1)`` nT; the filter starts with Q (of the drift) and R
                            each 10 to 100 times off (variance, either way) and a confident,
                            wrong prior on T_p (std ``10^U(0, 1.5)`` nT around zero, against a
                            permanent field of hundreds of nT) — Q and R must be found per
                            flight: too small a Q lags the drift, too large follows the noise
``nonstationary``           ``nominal`` physics over 1200 s with three noise regimes (white
                            noise std drawn from {1, 5, 15} nT per regime, switching at random
                            times) and one or two interference steps (equipment switching on:
                            ``T_p`` jumps by N(0, 30²) nT per axis) — both R and Q must move
``calibration_then_survey`` ``nominal`` box, descent and survey lines (1500 s); the survey
                            equipment switches on at the first line (a ``T_p`` step of
                            N(0, 30²) nT per axis): the filter learns in the box, must take the
                            step and then hold on the poorly excited lines
``noise_bursts``            1200 s of boxes with 4 to 8 bursts of equipment noise (HF radio,
                            heaters: 5–60 s of white noise, std ``10^U(1.7, 2.3)`` nT) — R must
                            rise for a burst and fall after it
``degradation``             1200 s of boxes; the fluxgate's white noise grows linearly from
                            1 nT, from a random onset, to ``10^U(1.2, 2)`` nT at the end — R must
                            follow a slow trend
``manoeuvre_heavy``         1200 s of boxes at twice the swing (20° roll, 10° pitch and yaw);
                            airframe flex and control-surface currents add noise proportional to
                            the angular rate (``10^U(1, 1.5)`` nT at 0.1 rad/s) — R must move
                            with the manoeuvres
``nonstationary_dense``     ``nonstationary`` with 4 to 8 interference steps: a training
                            variant that shows a learner the rare event more often
``suite``                   training only: each episode one of :data:`SUITE` (drawn from the
                            seed with :data:`SUITE_WEIGHTS`, ``nonstationary`` flown as
                            ``nonstationary_dense``), for the general policy
=========================== ================================================================

In ``noise_bursts``, ``degradation`` and ``manoeuvre_heavy`` the permanent field also drifts with
the temperature (``10^U(−1.5, −1)`` nT per sample) at a rate the filter knows (its T_p Q), so the
filter keeps tracking and a wrong R costs accuracy (with constant coefficients a converged filter
hardly listens to the data, whatever R is); their sensor noise is white (no FOGM), so that the
true noise variance is the right R.

Every episode also carries the true noise variance per sample and the Q the truth implies
(for the ``oracle`` and ``privileged`` policies and for analysis) and the true interference
(for the reward).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from aeromag_env.compensation.compensate import earth_model
from aeromag_env.compensation.model import FilterConfig, paper_filter_config
from aeromag_env.environment.ids import SCENARIOS, SUITE, TRAINING_SCENARIOS
from aeromag_env.errors import ConfigError
from aeromag_env.flight.data import Flight
from aeromag_env.simulation.config import SimulationConfig, preset, with_overrides
from aeromag_env.simulation.simulate import simulate_flight
from aeromag_env.simulation.trajectory import FIRST_SURVEY_LINE

#: Noise regimes of ``nonstationary``: white-noise std per axis [nT].
REGIME_STD_NT = (1.0, 5.0, 15.0)
#: Std of each interference step (``nonstationary``, ``calibration_then_survey``), per axis [nT].
STEP_STD_NT = 30.0
#: Interference steps per flight (inclusive range): ``nonstationary`` and ``nonstationary_dense``.
STEP_COUNTS = {"nonstationary": (1, 2), "nonstationary_dense": (4, 8)}
#: Flight length of the scenarios flown for a fixed time [s] (the others fly their pattern).
DURATION_S = {
    "misspecified": 1200.0,
    "nonstationary": 1200.0,
    "nonstationary_dense": 1200.0,
    "calibration_then_survey": 1500.0,
    "noise_bursts": 1200.0,
    "degradation": 1200.0,
    "manoeuvre_heavy": 1200.0,
}
#: ``misspecified``: log10 range of the permanent field's drift per sample [nT] (random walk),
#: of the size of the filter's variance errors (Q and R, each too large or too small by that
#: many decades) and of its prior std on T_p [nT].
DRIFT_LOG10_NT = (-1.0, 0.0)
MISSPECIFIED_LOG10_VARIANCE = (1.0, 2.0)
#: ``misspecified``: log10 range of the fluxgate's white noise [nT] (constant over a flight).
MISSPECIFIED_WHITE_LOG10_NT = (0.0, 1.0)
PRIOR_TP_LOG10_NT = (0.0, 1.5)
#: ``suite``: how often each scenario is drawn relative to the others, ∝ 1 / its flight length so
#: that each gives about as many training steps (``paper`` flies one 527-s box; others 1200 s).
SUITE_WEIGHTS = {"paper": 2.3, "calibration_then_survey": 0.8}
#: Scenarios whose permanent field drifts with the airframe's temperature at a rate the filter
#: knows (its T_p Q), and that drift's log10 range per sample [nT]: R must follow the noise
#: while T_p is being tracked.
DRIFTING, DRIFTING_LOG10_NT = ("noise_bursts", "degradation", "manoeuvre_heavy"), (-1.5, -1.0)
#: ``noise_bursts``: bursts per flight (inclusive), length [s] and log10 std [nT] of each.
BURST_COUNT, BURST_S, BURST_LOG10_NT = (4, 8), (5.0, 60.0), (1.7, 2.3)
#: ``degradation``: onset as a fraction of the flight, log10 of the final white-noise std [nT].
DEGRADATION_ONSET, DEGRADATION_LOG10_NT = (0.1, 0.6), (1.2, 2.0)
#: ``manoeuvre_heavy``: the box's swing factor, the flex noise std [nT] at ``FLEX_RATE_RAD_S``
#: (log10 range).
SWING_FACTOR, FLEX_LOG10_NT, FLEX_RATE_RAD_S = 2.0, (1.0, 1.5), 0.1


@dataclass
class Episode:
    """Signals of one episode (n samples).

    Attributes
    ----------
    y : (n, 3) ``T_m − T`` [nT]; t_b, tdot_b : (n, 3) model field [nT] and rate [nT/s]
    truth_interf : (n, 3) true interference at the fluxgate [nT]
    noise_var : (n,) true per-axis variance of the sensor noise [nT²] (white + FOGM)
    filter_cfg : the filter's initial tuning
    flight : the simulated flight (after the scenario's modifications)
    step_samples : sorted sample indices at which an interference step starts (``nonstationary``
        scenarios, ``calibration_then_survey``; empty otherwise): what a privileged policy may
        know
    q_log10_true : the Q the truth implies, as log10 of its ratio to the filter's initial Q, for
        the induced and eddy blocks (the package's well-tuned Q) and for T_p between steps (−inf:
        constant, Q = 0; where the permanent field drifts, the drift's variance per sample)
    scenario : the scenario flown (for ``suite``, the one drawn)
    """

    y: np.ndarray
    t_b: np.ndarray
    tdot_b: np.ndarray
    truth_interf: np.ndarray
    noise_var: np.ndarray
    filter_cfg: FilterConfig
    flight: Flight
    step_samples: np.ndarray = field(default_factory=lambda: np.empty(0, np.int64))
    q_log10_true: tuple[float, float] = (0.0, 0.0)
    scenario: str = ""

    @property
    def n(self) -> int:
        return int(self.y.shape[0])


def check_scenario(name: str) -> str:
    """Return ``name`` if known; else a one-line error listing the valid ones."""
    known = SCENARIOS + TRAINING_SCENARIOS
    if name not in known:
        raise ConfigError(f"unknown scenario {name!r}; valid scenarios: {', '.join(known)}")
    return name


def make_episode(name: str, seed: int, duration_s: float | None = None) -> Episode:
    """Build the episode of scenario ``name`` for ``seed`` (deterministic).

    ``duration_s`` overrides the scenario's flight length.
    """
    check_scenario(name)
    rng = np.random.default_rng(seed)
    if name == "suite":
        weights = np.array([SUITE_WEIGHTS.get(s, 1.0) for s in SUITE])
        drawn = SUITE[int(rng.choice(len(SUITE), p=weights / weights.sum()))]
        flown = "nonstationary_dense" if drawn == "nonstationary" else drawn
        return make_episode(flown, int(rng.integers(2**31)), duration_s)
    sim_seed = int(rng.integers(2**31))
    sim_cfg, filter_cfg, drift_std = _settings(name, rng)
    if duration_s is not None:
        sim_cfg = with_overrides(sim_cfg, {"trajectory.duration_s": duration_s})
    flight = simulate_flight(sim_cfg, sim_seed)
    noise_var = np.full(flight.n, _noise_var(sim_cfg))
    white = sim_cfg.fluxgate_noise.white_std_nt
    change = Change(flight.vector("flux_a"), flight.vector("truth_interf"), noise_var)
    if drift_std > 0.0:
        _drift(change, drift_std, rng)
    if name == "misspecified":
        change.steps.append(0)  # the confident prior on T_p is off by the permanent field
    if name in STEP_COUNTS:
        _noise_regimes(change, white, rng)
        _steps(change, STEP_COUNTS[name], rng)
    elif name == "calibration_then_survey":
        survey = np.flatnonzero(flight.fields["line"] >= FIRST_SURVEY_LINE)
        if survey.size:
            _step_at(change, int(survey[0]), rng)
    elif name == "noise_bursts":
        _bursts(change, sim_cfg.trajectory.sample_rate_hz, rng)
    elif name == "degradation":
        _degradation(change, white, rng)
    elif name == "manoeuvre_heavy":
        _flex_noise(change, flight, rng)
    flight = change.apply(flight)
    t_b, tdot_b = earth_model(flight, filter_cfg.rate_scheme)
    return Episode(
        y=flight.vector("flux_a") - t_b,
        t_b=t_b,
        tdot_b=tdot_b,
        truth_interf=flight.vector("truth_interf"),
        noise_var=change.noise_var,
        filter_cfg=filter_cfg,
        flight=flight,
        step_samples=np.sort(np.asarray(change.steps, np.int64)),
        q_log10_true=_q_log10_true(filter_cfg, drift_std),
        scenario=name,
    )


@dataclass
class Change:
    """What a scenario adds to the simulated flight: to the fluxgate (noise) or to the fluxgate
    and the truth alike (interference), with the noise variance and the steps kept in step."""

    flux: np.ndarray
    interf: np.ndarray
    noise_var: np.ndarray
    steps: list[int] = field(default_factory=list)

    def add_noise(
        self, lo: int, hi: int, std: np.ndarray | float, rng: np.random.Generator
    ) -> None:
        std = np.broadcast_to(np.asarray(std, float), (hi - lo,))
        self.flux[lo:hi] += std[:, None] * rng.standard_normal((hi - lo, 3))
        self.noise_var[lo:hi] += std**2

    def add_interference(self, start: int, signal: np.ndarray) -> None:
        self.flux[start:] += signal
        self.interf[start:] += signal

    def apply(self, flight: Flight) -> Flight:
        fields = dict(flight.fields)
        for i, axis in enumerate("xyz"):
            fields[f"flux_a_{axis}"] = self.flux[:, i]
            fields[f"truth_interf_{axis}"] = self.interf[:, i]
        return Flight(fields, flight.attrs)


def _settings(name: str, rng: np.random.Generator) -> tuple[SimulationConfig, FilterConfig, float]:
    """The simulation, the filter's initial tuning and (``misspecified``) the permanent field's
    drift std per sample [nT] (0 without a drift)."""
    if name == "paper":
        return preset("paper"), paper_filter_config("kf"), 0.0
    sim = preset("nominal")
    if name in DURATION_S:
        sim = with_overrides(sim, {"trajectory.duration_s": DURATION_S[name]})
    if name == "calibration_then_survey":
        sim = with_overrides(sim, {"trajectory.pattern": "calibration+survey"})
    if name == "manoeuvre_heavy":
        cal = sim.trajectory.calibration
        sim = with_overrides(
            sim,
            {
                f"trajectory.calibration.{k}_amplitude_deg": SWING_FACTOR
                * getattr(cal, f"{k}_amplitude_deg")
                for k in ("roll", "pitch", "yaw")
            },
        )
    base = FilterConfig()
    if name in DRIFTING:
        # the temperature drift, known to the filter: its Q for T_p is the drift's variance;
        # white sensor noise (no FOGM), so that the true noise variance is the right R
        drift = 10.0 ** rng.uniform(*DRIFTING_LOG10_NT)
        sim = with_overrides(sim, {"fluxgate_noise.fogm_std_nt": 0.0})
        return sim, replace(base, q_std=(float(drift), *base.q_std[1:])), float(drift)
    if name != "misspecified":
        return sim, base, 0.0
    drift = 10.0 ** rng.uniform(*DRIFT_LOG10_NT)
    white = 10.0 ** rng.uniform(*MISSPECIFIED_WHITE_LOG10_NT)
    sim = with_overrides(
        sim, {"fluxgate_noise.white_std_nt": white, "fluxgate_noise.fogm_std_nt": 0.0}
    )
    # each off by 10 to 100 times, either way
    q_factor, r_factor = 10.0 ** (
        rng.choice([-1.0, 1.0], 2) * rng.uniform(*MISSPECIFIED_LOG10_VARIANCE, 2)
    )
    prior_tp = 10.0 ** rng.uniform(*PRIOR_TP_LOG10_NT)
    q_std = (drift, *base.q_std[1:])
    cfg = replace(
        base,
        q_std=tuple(float(q * np.sqrt(q_factor)) for q in q_std),
        r_std_nt=float(np.sqrt(_noise_var(sim) * r_factor)),
        p0_std=(prior_tp, *base.p0_std[1:]),
    )
    return sim, cfg, float(drift)


def _noise_var(cfg: SimulationConfig) -> float:
    noise = cfg.fluxgate_noise
    return noise.white_std_nt**2 + noise.fogm_std_nt**2


def _q_log10_true(cfg: FilterConfig, drift_std: float) -> tuple[float, float]:
    """log10 of the true Q over the filter's initial Q, for the induced and eddy blocks (the
    package's well-tuned Q: they are constant, and its tiny Q absorbs what the Earth model leaves
    in them; the mean of the two blocks) and for T_p: −inf where it is constant between steps
    (Q = 0), the drift's variance per sample where the permanent field drifts."""
    good = FilterConfig().q_std
    blocks = float(np.mean([2.0 * np.log10(good[b] / cfg.q_std[b]) for b in (1, 2)]))
    tp = -np.inf if drift_std == 0.0 else float(2.0 * np.log10(drift_std / cfg.q_std[0]))
    return blocks, tp


def _noise_regimes(change: Change, white_std: float, rng: np.random.Generator) -> None:
    """Three noise regimes (white std from :data:`REGIME_STD_NT`, realised by adding white noise
    to the configured ``white_std``), switching at two random samples."""
    n = change.flux.shape[0]
    cuts = np.sort(rng.integers(n // 6, n - n // 6, 2))
    for lo, hi in zip(np.r_[0, cuts], np.r_[cuts, n], strict=True):
        std = float(rng.choice(REGIME_STD_NT))
        change.add_noise(int(lo), int(hi), np.sqrt(max(std**2 - white_std**2, 0.0)), rng)


def _steps(change: Change, step_count: tuple[int, int], rng: np.random.Generator) -> None:
    """``step_count`` (lo, hi inclusive) interference steps at random samples."""
    n = change.flux.shape[0]
    count = int(rng.integers(step_count[0], step_count[1] + 1))
    for start in rng.integers(n // 5, n - n // 10, count):
        _step_at(change, int(start), rng)


def _step_at(change: Change, start: int, rng: np.random.Generator) -> None:
    """Equipment switching on at ``start``: T_p jumps by N(0, STEP_STD_NT²) per axis."""
    change.add_interference(start, rng.normal(0.0, STEP_STD_NT, 3))
    change.steps.append(start)


def _drift(change: Change, std: float, rng: np.random.Generator) -> None:
    """The permanent field's temperature drift: a random walk of per-sample std ``std`` [nT]
    per axis, from zero at the start."""
    walk = np.cumsum(std * rng.standard_normal(change.flux.shape), axis=0)
    change.add_interference(0, walk)


def _bursts(change: Change, rate_hz: float, rng: np.random.Generator) -> None:
    """Bursts of equipment noise: :data:`BURST_COUNT` of them, each :data:`BURST_S` long with a
    white-noise std of ``10^U(BURST_LOG10_NT)`` nT (they may overlap)."""
    n = change.flux.shape[0]
    count = int(rng.integers(BURST_COUNT[0], BURST_COUNT[1] + 1))
    for _ in range(count):
        length = max(1, round(rng.uniform(*BURST_S) * rate_hz))
        start = int(rng.integers(0, max(1, n - length)))
        change.add_noise(start, min(n, start + length), 10.0 ** rng.uniform(*BURST_LOG10_NT), rng)


def _degradation(change: Change, white_std: float, rng: np.random.Generator) -> None:
    """The fluxgate's white noise grows linearly from ``white_std`` at a random onset to
    ``10^U(DEGRADATION_LOG10_NT)`` nT at the last sample (extra noise added in quadrature)."""
    n = change.flux.shape[0]
    onset = int(rng.uniform(*DEGRADATION_ONSET) * n)
    final = 10.0 ** rng.uniform(*DEGRADATION_LOG10_NT)
    std = white_std + (final - white_std) * np.linspace(0.0, 1.0, n - onset)
    change.add_noise(onset, n, np.sqrt(np.maximum(std**2 - white_std**2, 0.0)), rng)


def _flex_noise(change: Change, flight: Flight, rng: np.random.Generator) -> None:
    """Airframe flex and control-surface currents: white noise whose std is proportional to the
    angular rate, ``10^U(FLEX_LOG10_NT)`` nT at :data:`FLEX_RATE_RAD_S` (from the INS attitude)."""
    angles = np.deg2rad(
        np.column_stack([flight.fields[f"ins_{a}"] for a in ("roll", "pitch", "yaw")])
    )
    dt = np.gradient(np.asarray(flight.fields["tt"], float))
    rate = np.linalg.norm(np.gradient(np.unwrap(angles, axis=0), axis=0), axis=1) / dt
    scale = 10.0 ** rng.uniform(*FLEX_LOG10_NT)
    change.add_noise(0, change.flux.shape[0], scale * rate / FLEX_RATE_RAD_S, rng)
