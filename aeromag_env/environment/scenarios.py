"""Named scenarios of the tuning environment: one seed → one episode's signals and initial tuning.

=========================== ================================================================
scenario                    what varies and what the tuner must do
=========================== ================================================================
``paper``                   the paper's §4: 20 nT white noise per axis, ``R(0) = 2e-3 nT²``,
                            ``Q(0) = 1e-3 I`` (normalised); one calibration box
``nominal``                 realistic installation (1 nT white + 1 nT FOGM), the package's
                            well-tuned filter defaults; one calibration box
``misspecified``            ``nominal`` with the initial Q and R each off by a factor
                            ``10^U(−2, 2)`` (up to 100× either way), drawn per episode
``nonstationary``           ``nominal`` physics over 1200 s with three noise regimes (white
                            noise std drawn from {1, 5, 15} nT per regime, switching at random
                            times) and one or two interference steps (equipment switching on:
                            ``T_p`` jumps by N(0, 30²) nT per axis) — both R and Q must move
``nonstationary_dense``     ``nonstationary`` with 4 to 8 interference steps: a training
                            variant that shows a learner the rare event more often
``calibration_then_survey`` ``nominal`` box, descent and survey lines (1500 s): the filter learns
                            in the box and must not drift in the poorly excited survey
=========================== ================================================================

Every episode also carries the true noise variance per sample (for the ``oracle`` policy and
for analysis) and the true interference (for the reward).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from aeromag_env.compensation.compensate import earth_model
from aeromag_env.compensation.model import FilterConfig, paper_filter_config
from aeromag_env.environment.ids import SCENARIOS, TRAINING_SCENARIOS
from aeromag_env.errors import ConfigError
from aeromag_env.flight.data import Flight
from aeromag_env.simulation.config import SimulationConfig, preset, with_overrides
from aeromag_env.simulation.simulate import simulate_flight

#: Noise regimes of ``nonstationary``: white-noise std per axis [nT].
REGIME_STD_NT = (1.0, 5.0, 15.0)
#: Std of each interference step of ``nonstationary``, per axis [nT].
STEP_STD_NT = 30.0
#: Interference steps per flight (inclusive range): ``nonstationary`` and ``nonstationary_dense``.
STEP_COUNTS = {"nonstationary": (1, 2), "nonstationary_dense": (4, 8)}


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
        scenarios; empty otherwise): what a privileged policy may know
    """

    y: np.ndarray
    t_b: np.ndarray
    tdot_b: np.ndarray
    truth_interf: np.ndarray
    noise_var: np.ndarray
    filter_cfg: FilterConfig
    flight: Flight
    step_samples: np.ndarray = field(default_factory=lambda: np.empty(0, np.int64))

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
    sim_seed = int(rng.integers(2**31))
    sim_cfg, filter_cfg = _settings(name, rng)
    if duration_s is not None:
        sim_cfg = with_overrides(sim_cfg, {"trajectory.duration_s": duration_s})
    flight = simulate_flight(sim_cfg, sim_seed)
    noise_var = np.full(flight.n, _noise_var(sim_cfg))
    steps = np.empty(0, np.int64)
    if name in STEP_COUNTS:
        white = sim_cfg.fluxgate_noise.white_std_nt
        flight, noise_var, steps = _nonstationary(flight, noise_var, white, STEP_COUNTS[name],
                                                  rng)  # fmt: skip
    t_b, tdot_b = earth_model(flight, filter_cfg.rate_scheme)
    return Episode(
        y=flight.vector("flux_a") - t_b,
        t_b=t_b,
        tdot_b=tdot_b,
        truth_interf=flight.vector("truth_interf"),
        noise_var=noise_var,
        filter_cfg=filter_cfg,
        flight=flight,
        step_samples=steps,
    )


def _settings(name: str, rng: np.random.Generator) -> tuple[SimulationConfig, FilterConfig]:
    if name == "paper":
        return preset("paper"), paper_filter_config("kf")
    nominal = preset("nominal")
    if name == "nominal":
        return nominal, FilterConfig()
    if name == "misspecified":
        q_factor, r_factor = 10.0 ** rng.uniform(-2.0, 2.0, 2)  # variance factors
        base = FilterConfig()
        cfg = replace(
            base,
            q_std=tuple(q * np.sqrt(q_factor) for q in base.q_std),
            r_std_nt=base.r_std_nt * float(np.sqrt(r_factor)),
        )
        return nominal, cfg
    if name in STEP_COUNTS:
        return with_overrides(nominal, {"trajectory.duration_s": 1200.0}), FilterConfig()
    pattern = {"trajectory.pattern": "calibration+survey", "trajectory.duration_s": 1500.0}
    return with_overrides(nominal, pattern), FilterConfig()


def _noise_var(cfg: SimulationConfig) -> float:
    noise = cfg.fluxgate_noise
    return noise.white_std_nt**2 + noise.fogm_std_nt**2


def _nonstationary(
    flight: Flight,
    noise_var: np.ndarray,
    white_std: float,
    step_count: tuple[int, int],
    rng: np.random.Generator,
) -> tuple[Flight, np.ndarray, np.ndarray]:
    """Three noise regimes (white std from :data:`REGIME_STD_NT`, realised by adding white noise
    to the configured ``white_std``) and ``step_count`` (lo, hi inclusive) interference steps, in
    fluxgate and truth; returns the flight, the noise variance and the steps' sorted samples."""
    n = flight.n
    cuts = np.sort(rng.integers(n // 6, n - n // 6, 2))
    fields = dict(flight.fields)
    flux = flight.vector("flux_a")
    interf = flight.vector("truth_interf")
    base_var = noise_var[0]
    noise_var = noise_var.copy()
    for lo, hi in zip(np.r_[0, cuts], np.r_[cuts, n], strict=True):
        std = float(rng.choice(REGIME_STD_NT))
        extra = np.sqrt(max(std**2 - white_std**2, 0.0))
        flux[lo:hi] += extra * rng.standard_normal((hi - lo, 3))
        noise_var[lo:hi] = base_var + extra**2
    count = int(rng.integers(step_count[0], step_count[1] + 1))
    starts = rng.integers(n // 5, n - n // 10, count)
    for start in starts:
        step = rng.normal(0.0, STEP_STD_NT, 3)
        flux[start:] += step
        interf[start:] += step
    for i, axis in enumerate("xyz"):
        fields[f"flux_a_{axis}"] = flux[:, i]
        fields[f"truth_interf_{axis}"] = interf[:, i]
    return Flight(fields, flight.attrs), noise_var, np.sort(starts).astype(np.int64)
