"""Hidden-effect suite for the discrepancy workflow: flights with known injected effects.

Every case simulates a 30-minute calibration-then-survey flight (box at 3000 m, descent, lines at
400 m) with the suite's auxiliary channels — a strobe, three switched loads, a fluxgate
temperature and a wandering bus voltage — of which only those an injected effect follows carry
a field; the others are decoys. The base physics is the ``nominal`` preset without external
variation (that is an effect here) and without the scalar sensor.

Effect strength is set by the identifiable signal-to-noise ratio: the RMS of the injected field
after projecting out the 21 base regressors (on the whole flight, with the true Earth field),
divided by the fluxgate noise std ``sqrt(white² + fogm²)``. The raw injected RMS is recorded too.

Case kinds: ``null`` (nominal noise), ``coloured_null`` (other noise colours), ``single``,
``absorbed`` (effects the base model absorbs), ``pair``, and ``duration`` (each single effect at
a low SNR on flights of ``DURATIONS_S``: the box and the descent take 879 s, so the shortest,
1200 s, still has 5 min of survey lines). Seeds of each kind are disjoint.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from aeromag_env.discovery.base_model import BaseSpan, base_columns
from aeromag_env.discovery.workflow import discover
from aeromag_env.flight.data import Flight
from aeromag_env.geo.frames import time_derivative
from aeromag_env.simulation.config import (
    AuxChannelConfig,
    EffectConfig,
    SensorNoiseConfig,
    SimulationConfig,
    preset,
    with_overrides,
)
from aeromag_env.simulation.simulate import simulate_flight

AUX = (
    AuxChannelConfig(name="cur_strb", kind="strobe", level=2.0, period_s=1.0),
    AuxChannelConfig(name="cur_ac_hi", kind="switching", level=6.0, period_s=120.0),
    AuxChannelConfig(name="cur_com_1", kind="switching", level=3.0, period_s=20.0),
    AuxChannelConfig(name="cur_tank", kind="switching", level=4.0, period_s=300.0),
    AuxChannelConfig(name="temp_flux", kind="temperature", level=10.0, period_s=450.0),
    AuxChannelConfig(name="vol_bus", kind="random_walk", level=0.5, period_s=60.0, offset=28.0),
)
#: Channels an injected onboard_current may follow (the rest stay decoys).
CURRENT_CHANNELS = ("cur_strb", "cur_ac_hi", "cur_com_1")
SNRS = (0.5, 1.0, 2.0, 4.0)
#: Flight durations [s] and SNRs of the ``duration`` cases (SNRs where power is not saturated).
DURATIONS_S = (1200.0, 1800.0, 2700.0, 3600.0)
DURATION_SNRS = (0.1, 0.25, 0.5)
SINGLE = (
    "onboard_current",
    "external_field_variation",
    "permanent_field_drift",
    "induced_second_order",
    "altitude_gradient",
    "eddy_time_constant",
    "sensor_lag",
)
ABSORBED_CASES = ("fluxgate_offset", "fluxgate_scale", "fluxgate_nonorthogonality", "misalignment")
PAIRS = (
    ("onboard_current", "altitude_gradient"),
    ("external_field_variation", "permanent_field_drift"),
    ("eddy_time_constant", "induced_second_order"),
    ("sensor_lag", "onboard_current"),
)
COLOURED_NOISE = (
    SensorNoiseConfig(white_std_nt=1.0, fogm_std_nt=3.0, fogm_tau_s=120.0),
    SensorNoiseConfig(white_std_nt=1.0, fogm_std_nt=2.0, fogm_tau_s=1800.0),
    SensorNoiseConfig(white_std_nt=3.0, fogm_std_nt=1.0, fogm_tau_s=600.0),
    SensorNoiseConfig(white_std_nt=0.5, fogm_std_nt=0.0, fogm_tau_s=600.0),
)
#: Seed offsets per case kind (disjoint ranges).
SEED_BASE = {
    "null": 0,
    "coloured_null": 10_000,
    "single": 20_000,
    "absorbed": 30_000,
    "pair": 40_000,
    # 50000+ and 60000+ were development and plain-flight seeds (experiments.discovery_*)
    "duration": 70_000,
}


def base_config(duration_s: float = 1800.0) -> SimulationConfig:
    """The suite's flight without any effect."""
    cfg = with_overrides(
        preset("nominal"),
        {
            "trajectory.pattern": "calibration+survey",
            "trajectory.duration_s": duration_s,
            "earth.daily_amplitude_nt": 0.0,
            "earth.external_fogm_std_nt": 0.0,
            "scalar.enabled": False,
        },
    )
    return dataclasses.replace(cfg, aux_channels=AUX, preset="discovery_suite")


def _unit(rng: np.random.Generator, size: int) -> np.ndarray:
    v = rng.standard_normal(size)
    return v / np.linalg.norm(v)


def prototype(name: str, rng: np.random.Generator) -> tuple[EffectConfig, float]:
    """An effect of unit strength with a random direction, and the exponent of its
    identifiable RMS in the strength scale (2 for a lag: the identifiable part is τ²/2 T̈)."""
    if name == "onboard_current":
        ch = CURRENT_CHANNELS[int(rng.integers(len(CURRENT_CHANNELS)))]
        return EffectConfig(
            name=name, channel=ch, parameters={"k_nt_per_unit": _unit(rng, 3).tolist()}
        ), 1
    if name == "external_field_variation":
        return EffectConfig(
            name=name,
            parameters={
                "offset_ned_nt": _unit(rng, 3).tolist(),
                "daily_amplitude_nt": 1.0,
                "fogm_std_nt": 0.3,
                "fogm_tau_s": 900.0,
                "smoothing_s": 180.0,
            },
        ), 1
    if name == "permanent_field_drift":
        return EffectConfig(
            name=name, channel="temp_flux", parameters={"k_nt_per_unit": _unit(rng, 3).tolist()}
        ), 1
    if name == "induced_second_order":
        return EffectConfig(name=name, parameters={"coefficients": _unit(rng, 18).tolist()}), 1
    if name == "altitude_gradient":
        return EffectConfig(
            name=name,
            parameters={
                "gradient_ned_nt_per_m": (1e-3 * _unit(rng, 3)).tolist(),
                "reference_alt_m": 1500.0,
            },
        ), 1
    if name == "eddy_time_constant":
        return EffectConfig(
            name=name, parameters={"tau_s": 0.2, "eddy_s": (1e-3 * _unit(rng, 9)).tolist()}
        ), 1
    if name == "sensor_lag":
        return EffectConfig(name=name, parameters={"lag_s": 0.02}), 2
    if name == "fluxgate_offset":
        return EffectConfig(name=name, parameters={"offset_nt": (50.0 * _unit(rng, 3)).tolist()}), 1
    if name == "fluxgate_scale":
        return EffectConfig(name=name, parameters={"scale": (2e-3 * _unit(rng, 3)).tolist()}), 1
    if name in ("fluxgate_nonorthogonality", "misalignment"):
        return EffectConfig(
            name=name, parameters={"angles_rad": (2e-3 * _unit(rng, 3)).tolist()}
        ), 1
    raise ValueError(f"no prototype for {name}")


def _scaled(eff: EffectConfig, factor: float) -> EffectConfig:
    amplitude = {
        "k_nt_per_unit",
        "offset_ned_nt",
        "daily_amplitude_nt",
        "fogm_std_nt",
        "coefficients",
        "gradient_ned_nt_per_m",
        "eddy_s",
        "lag_s",
        "offset_nt",
        "scale",
        "angles_rad",
    }
    params = {
        k: (np.asarray(v, float) * factor).tolist() if k in amplitude else v
        for k, v in eff.parameters.items()
    }
    return dataclasses.replace(eff, parameters=params)


def identifiable_rms(flight: Flight) -> float:
    """RMS of ``truth_effects`` outside the base span (true Earth field, whole flight) [nT]."""
    t_b = flight.vector("truth_earth")
    span = BaseSpan(
        base_columns(t_b, time_derivative(t_b, flight.tt, "central")), np.ones(flight.n, bool)
    )
    return float(np.sqrt(np.mean(span.perp(flight.vector("truth_effects")[:, :, None]) ** 2)))


@dataclass
class Case:
    kind: str
    seed: int
    effects: tuple[str, ...] = ()
    snr: float | None = None
    noise: SensorNoiseConfig | None = None
    label: str = ""
    detail: dict[str, Any] = field(default_factory=dict)
    duration_s: float = 1800.0


def build_case(case: Case) -> tuple[SimulationConfig, dict[str, Any]]:
    """The configuration of a case with its effects scaled to the case's SNR, and the truth."""
    cfg = base_config(case.duration_s)
    if case.noise is not None:
        cfg = dataclasses.replace(cfg, fluxgate_noise=case.noise)
    rng = np.random.default_rng([case.seed, 7])
    protos = [prototype(nm, rng) for nm in case.effects]
    truth: dict[str, Any] = {"effects": [], "snr": case.snr}
    if not protos:
        return cfg, truth
    noise = cfg.fluxgate_noise
    sigma = math.hypot(noise.white_std_nt, noise.fogm_std_nt)
    if case.kind == "absorbed":  # nothing identifiable to scale: the prototype's raw strength
        truth["effects"] = [
            {"name": e.name, "channel": e.channel, "parameters": e.parameters} for e, _ in protos
        ]
        return dataclasses.replace(cfg, effects=tuple(e for e, _ in protos)), truth
    scaled = []
    for eff, power in protos:
        probe = simulate_flight(dataclasses.replace(cfg, effects=(eff,)), case.seed)
        rms = identifiable_rms(probe)
        target = (case.snr or 4.0) * sigma
        factor = (target / rms) ** (1.0 / power) if rms > 0 else 1.0
        eff = _scaled(eff, factor)
        if power != 1:  # one refinement for a nonlinear strength
            rms = identifiable_rms(
                simulate_flight(dataclasses.replace(cfg, effects=(eff,)), case.seed)
            )
            eff = _scaled(eff, (target / rms) ** (1.0 / power))
        scaled.append(eff)
    cfg = dataclasses.replace(cfg, effects=tuple(scaled))
    truth["effects"] = [
        {"name": e.name, "channel": e.channel, "parameters": e.parameters} for e in scaled
    ]
    return cfg, truth


def suite_cases(
    n_null: int = 60,
    n_coloured: int = 20,
    n_single: int = 20,
    n_absorbed: int = 10,
    n_pair: int = 10,
    n_duration: int = 0,
) -> list[Case]:
    """The suite's cases (sizes per cell; ``n_duration`` per effect, duration and SNR)."""
    cases = [Case("null", SEED_BASE["null"] + s) for s in range(n_null)]
    cases += [
        Case(
            "coloured_null",
            SEED_BASE["coloured_null"] + s,
            noise=COLOURED_NOISE[s % len(COLOURED_NOISE)],
        )
        for s in range(n_coloured)
    ]
    k = SEED_BASE["single"]
    for nm in SINGLE:
        for snr in SNRS:
            for _ in range(n_single):
                cases.append(Case("single", k, (nm,), snr))
                k += 1
    k = SEED_BASE["absorbed"]
    for nm in ABSORBED_CASES:
        for _ in range(n_absorbed):
            cases.append(Case("absorbed", k, (nm,)))
            k += 1
    k = SEED_BASE["pair"]
    for pair in PAIRS:
        for _ in range(n_pair):
            cases.append(Case("pair", k, pair, 4.0))
            k += 1
    k = SEED_BASE["duration"]
    for nm in SINGLE:
        for snr in DURATION_SNRS:
            for dur in DURATIONS_S:
                for _ in range(n_duration):
                    cases.append(Case("duration", k, (nm,), snr, duration_s=dur))
                    k += 1
    return cases


def run_case(case: Case) -> dict[str, Any]:
    """Simulate the case, run discovery, and score it against the truth."""
    cfg, truth = build_case(case)
    flight = simulate_flight(cfg, case.seed)
    raw = float(np.sqrt(np.mean(flight.vector("truth_effects") ** 2))) if cfg.effects else 0.0
    found = discover(flight).report
    named = [(e["name"], e["channel"]) for e in found["missing_effects"]]
    true = [(e["name"], e["channel"]) for e in truth["effects"] if e["name"] in SINGLE]
    coupled = {e["channel"] for e in truth["effects"] if e["channel"]}
    return {
        "kind": case.kind,
        "seed": case.seed,
        "effects": list(case.effects),
        "snr": case.snr,
        "duration_s": case.duration_s,
        "noise": dataclasses.asdict(case.noise) if case.noise else None,
        "raw_rms_nt": raw,
        "named": [list(t) for t in named],
        "truth": [list(t) for t in true],
        "exact": sorted(named, key=str) == sorted(true, key=str),
        "names_correct": sorted(n for n, _ in named) == sorted(n for n, _ in true),
        "absorbed_named": [n for n, _ in named if n in ABSORBED_CASES],
        "decoy_named": [c for n, c in named if c is not None and c not in coupled],
        "gap_before_nt": found["gap"]["rms_before_nt"],
        "gap_after_nt": found["gap"]["rms_after_nt"],
        "shrink": found["gap"]["shrink"],
        "caveats": len(found["caveats"]),
    }
