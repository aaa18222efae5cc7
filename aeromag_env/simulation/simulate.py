"""Simulate one flight: trajectory → Earth field → aircraft interference → sensors → Flight.

Every stage draws from its own child of the ``rng`` passed in (``rng.spawn``), so changing, say,
the sensor noise leaves the trajectory and the coefficients of the same seed unchanged.
"""

from __future__ import annotations

import dataclasses
import datetime as _dt
import json
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from aeromag_env.configs import to_json
from aeromag_env.errors import ConfigError
from aeromag_env.flight.data import Flight, vector_names
from aeromag_env.geo import earth
from aeromag_env.geo.crust_area import crust_along_track
from aeromag_env.geo.earth import external_variation_ned, igrf_ned_along_track, parse_date
from aeromag_env.geo.frames import dcm_from_euler, nav_to_body, time_derivative
from aeromag_env.simulation import trajectory
from aeromag_env.simulation.auxiliary import aux_channel
from aeromag_env.simulation.config import SimulationConfig
from aeromag_env.simulation.effects import EffectContext, simulate_effects
from aeromag_env.simulation.interference import (
    VectorCoefficients,
    draw_coefficients,
    scalar_interference,
    vector_interference,
)
from aeromag_env.simulation.sensors import sensor_noise
from aeromag_env.simulation.tolles_lawson_terms import coefficients_from_vector
from aeromag_env.simulation.trajectory import MANEUVER_KINDS, Trajectory, generate_trajectory

#: Simulation stages, in order, as reported to a progress callback.
STAGES = ("trajectory", "earth field", "interference", "sensors", "assemble")


def clear_caches() -> None:
    """Forget the remembered deterministic parts of earlier simulations (the trajectory pattern
    of a configuration and the IGRF along it): the next simulation is timed cold. Results do
    not depend on the caches."""
    trajectory._track.cache_clear()
    earth.clear_caches()


@dataclass(frozen=True)
class _Flown:
    """The trajectory stage: where and when the aircraft flies, and its auxiliary channels."""

    traj: Trajectory
    start: _dt.datetime
    dt: float
    aux: dict[str, np.ndarray]


@dataclass(frozen=True)
class _Ambient:
    """The Earth-field stage: main field, external variation and crustal anomaly (NED; None
    without geology), attitude and the body-frame ambient field with its time derivative."""

    earth_n: np.ndarray
    ext_n: np.ndarray
    crust_n: np.ndarray | None
    c_nb: np.ndarray
    t_b: np.ndarray
    tdot_b: np.ndarray


@dataclass(frozen=True)
class _Aircraft:
    """The interference stage: coefficients, their field at the fluxgate, and the configured
    effects' field (None without effects)."""

    coef: VectorCoefficients
    interf: np.ndarray
    extra: np.ndarray | None


@dataclass(frozen=True)
class _Scalar:
    """The scalar magnetometer: its measurement, its interference and its true coefficients."""

    measured: np.ndarray
    interf: np.ndarray
    coefficients: dict[str, Any]


def simulate_flight(
    config: SimulationConfig,
    rng: np.random.Generator | int,
    progress: Callable[[str], None] | None = None,
    replay: Flight | None = None,
) -> Flight:
    """Simulate one flight.

    Parameters
    ----------
    config : SimulationConfig
    rng : numpy.random.Generator or int
        Source of every random draw; an int is used as the seed (and recorded in the file).
    progress : callable, optional
        Called with each stage name of :data:`STAGES` as it starts.
    replay : Flight, optional
        Fly this flight's time, position, date, attitude, ``line``/``maneuver`` and auxiliary
        channels instead of ``config.trajectory`` (e.g. to re-simulate a measured flight with a
        discovered model). Its ``diurnal`` channel, if any, replaces the configured external
        variation (a base station sees it along the main field).

    Returns
    -------
    Flight
        Fields of DESIGN.md plus ``truth_earth_*`` (body-frame ambient field: IGRF + external
        variation + crustal anomaly), ``truth_crust_*`` (its crustal part, with
        ``config.geology``), ``truth_interf_*`` (interference at the fluxgate) and, with a
        scalar sensor, ``truth_interf_mag_N``; attributes ``date``, ``config`` (JSON),
        ``seed`` (if given), ``truth_coefficients`` (JSON) and ``maneuver_kinds`` (strings).
    """
    seed = rng if isinstance(rng, (int, np.integer)) else None
    gen = np.random.default_rng(rng)
    r_traj, r_earth, r_coef, r_flux, r_scalar, r_extra = gen.spawn(6)
    r_aux, r_fx, r_geo = r_extra.spawn(3)  # a third child leaves the first two as they were
    step = progress or (lambda _stage: None)

    step(STAGES[0])
    flown = _fly(config, replay, r_traj, r_aux)
    step(STAGES[1])
    ambient = _earth_field(config, flown, replay, (r_earth, r_geo))
    step(STAGES[2])
    coef, coef_s = _installation(config, r_coef, r_scalar)
    aircraft = _aircraft_field(config, flown, ambient, coef, r_fx)
    step(STAGES[3])
    fields = _fluxgate_fields(config, flown, ambient, aircraft, r_flux)
    coefficients: dict[str, dict] = {config.fluxgate: aircraft.coef.to_dict()}
    scalar = _scalar_channel(config, flown, ambient, coef_s, r_scalar)
    if scalar is not None:
        fields[config.scalar.name] = scalar.measured
        coefficients[config.scalar.name] = scalar.coefficients
    diurnal = _diurnal_channel(config, ambient, replay)
    if diurnal is not None:
        fields["diurnal"] = diurnal
    step(STAGES[4])
    fields.update(_truth_fields(config, flown.traj, ambient, aircraft, scalar))
    attrs = _attributes(config, flown.start, coefficients, seed, replay)
    return Flight(
        fields={k: np.ascontiguousarray(v, float) for k, v in fields.items()}, attrs=attrs
    )


def _fly(
    config: SimulationConfig,
    replay: Flight | None,
    r_traj: np.random.Generator,
    r_aux: np.random.Generator,
) -> _Flown:
    """Trajectory stage: the configured (or replayed) trajectory, its start time and sampling
    interval, and the auxiliary channels along it."""
    if replay is None:
        traj = generate_trajectory(config.trajectory, r_traj)
        dt = 1.0 / config.trajectory.sample_rate_hz
        start = parse_date(config.trajectory.date)
    else:
        traj, start = _replayed_trajectory(replay), replay.date()
        dt = float(np.median(np.diff(traj.tt)))
    aux = _aux_channels(config, traj.tt, replay, r_aux)
    return _Flown(traj=traj, start=start, dt=dt, aux=aux)


def _earth_field(
    config: SimulationConfig,
    flown: _Flown,
    replay: Flight | None,
    rngs: tuple[np.random.Generator, np.random.Generator],
) -> _Ambient:
    """Earth-field stage: IGRF along the track plus the external variation (the replayed
    flight's ``diurnal`` along the main field, else simulated, from ``rngs[0]``) and the
    crustal anomaly (from ``rngs[1]``), rotated into the body frame."""
    traj, start = flown.traj, flown.start
    r_earth, r_geo = rngs
    earth_n = igrf_ned_along_track(
        traj.tt, traj.lat, traj.lon, traj.alt, start, config.earth.igrf_grid_spacing_s
    )
    if replay is not None and "diurnal" in replay:
        unit = earth_n / np.linalg.norm(earth_n, axis=1, keepdims=True)
        ext_n = unit * replay["diurnal"][:, None]
    else:
        ext_n = external_variation_ned(
            traj.tt,
            start,
            config.earth.daily_amplitude_nt,
            config.earth.external_fogm_std_nt,
            config.earth.external_fogm_tau_s,
            r_earth,
            config.earth.external_smoothing_s,
        )
    crust_n = None
    if config.geology is not None:  # the area's ground with a seed, else one around the track
        crust_n = crust_along_track(
            traj.lat,
            traj.lon,
            traj.alt,
            r_geo,
            main_field_ned=earth_n.mean(axis=0),
            start_deg=(config.trajectory.start_lat_deg, config.trajectory.start_lon_deg),
            **dataclasses.asdict(config.geology),
        )
    ambient_n = earth_n + ext_n if crust_n is None else earth_n + ext_n + crust_n
    c_nb = dcm_from_euler(traj.roll, traj.pitch, traj.yaw)
    t_b = nav_to_body(c_nb, ambient_n)
    tdot_b = time_derivative(t_b, traj.tt, "central")
    return _Ambient(
        earth_n=earth_n, ext_n=ext_n, crust_n=crust_n, c_nb=c_nb, t_b=t_b, tdot_b=tdot_b
    )


def _installation(
    config: SimulationConfig, r_coef: np.random.Generator, r_scalar: np.random.Generator
) -> tuple[VectorCoefficients, VectorCoefficients | None]:
    """The fluxgate's and the scalar magnetometer's interference coefficients (None without a
    scalar): drawn from the flight's children ``r_coef`` and ``r_scalar``, or, with
    ``config.aircraft``, from the aircraft's seed, plus its maintenance shifts."""
    scalar = config.scalar.interference if config.scalar.enabled else None
    plane = config.aircraft
    if plane is None:
        coef = draw_coefficients(config.interference, r_coef)
        return coef, None if scalar is None else draw_coefficients(scalar, r_scalar)
    a_flux, a_scalar = np.random.default_rng(plane.seed).spawn(2)
    coef = _shifted(draw_coefficients(config.interference, a_flux), plane.permanent_shift_nt)
    if scalar is None:
        return coef, None
    coef_s = draw_coefficients(scalar, a_scalar)
    return coef, _shifted(coef_s, plane.scalar_permanent_shift_nt)


def _shifted(coef: VectorCoefficients, shift_nt: tuple[float, ...]) -> VectorCoefficients:
    """``coef`` with ``shift_nt`` (3,) [nT] added to its permanent field."""
    return dataclasses.replace(coef, permanent_nt=coef.permanent_nt + np.asarray(shift_nt, float))


def _aircraft_field(
    config: SimulationConfig,
    flown: _Flown,
    ambient: _Ambient,
    coef: VectorCoefficients,
    r_fx: np.random.Generator,
) -> _Aircraft:
    """Interference stage: the fluxgate's field (paper eq. 5) from its coefficients ``coef``
    and the configured effects on top of it."""
    interf = vector_interference(coef, ambient.t_b, ambient.tdot_b)
    extra = _effects_field(config, flown, ambient, interf, r_fx) if config.effects else None
    return _Aircraft(coef=coef, interf=interf, extra=extra)


def _effects_field(
    config: SimulationConfig,
    flown: _Flown,
    ambient: _Ambient,
    interf: np.ndarray,
    r_fx: np.random.Generator,
) -> np.ndarray:
    """The field the configured effects add to the fluxgate (n, 3) [nT]."""
    traj = flown.traj
    ctx = EffectContext(
        tt=traj.tt,
        c_nb=ambient.c_nb,
        t_b=ambient.t_b,
        tdot_b=ambient.tdot_b,
        t2dot_b=time_derivative(ambient.tdot_b, traj.tt, "central"),
        alt=traj.alt,
        aux=flown.aux,
        signal=ambient.t_b + interf,
        rng=r_fx,
        start=flown.start,
    )
    return simulate_effects(ctx, config.effects)


def _fluxgate_fields(
    config: SimulationConfig,
    flown: _Flown,
    ambient: _Ambient,
    aircraft: _Aircraft,
    r_flux: np.random.Generator,
) -> dict[str, np.ndarray]:
    """Sensor stage: navigation and auxiliary channels, then the noisy fluxgate."""
    traj = flown.traj
    noise = sensor_noise(traj.tt.size, flown.dt, config.fluxgate_noise, r_flux)
    flux = ambient.t_b + aircraft.interf + noise
    if aircraft.extra is not None:
        flux += aircraft.extra
    fields = _navigation_fields(traj, flown.start)
    fields.update(flown.aux)
    fields.update(zip(vector_names(config.fluxgate), flux.T, strict=True))
    return fields


def _scalar_channel(
    config: SimulationConfig,
    flown: _Flown,
    ambient: _Ambient,
    coef_s: VectorCoefficients | None,
    r_scalar: np.random.Generator,
) -> _Scalar | None:
    """The scalar magnetometer (None if disabled): its coefficients ``coef_s``
    (:func:`_installation`) and noise from ``r_scalar``."""
    scalar = config.scalar
    if not scalar.enabled or coef_s is None:
        return None
    interf_s = scalar_interference(coef_s, ambient.t_b, ambient.tdot_b)
    noise_s = sensor_noise(flown.traj.tt.size, flown.dt, scalar.noise, r_scalar, dims=1)
    coefficients = {
        **coef_s.to_dict(),
        "tolles_lawson": coefficients_from_vector(coef_s, flown.dt).tolist(),
    }
    return _Scalar(
        measured=np.linalg.norm(ambient.t_b, axis=1) + interf_s + noise_s,
        interf=interf_s,
        coefficients=coefficients,
    )


def _diurnal_channel(
    config: SimulationConfig, ambient: _Ambient, replay: Flight | None
) -> np.ndarray | None:
    """The base-station ``diurnal`` channel: the replayed one, else (with an external
    variation) its projection on the main-field direction, else None."""
    if replay is not None and "diurnal" in replay:
        return replay["diurnal"].copy()
    if config.earth.daily_amplitude_nt > 0 or config.earth.external_fogm_std_nt > 0:
        # a base-station total-field magnetometer sees the projection on the main-field direction
        unit = ambient.earth_n / np.linalg.norm(ambient.earth_n, axis=1, keepdims=True)
        return np.sum(unit * ambient.ext_n, axis=1)
    return None


def _truth_fields(
    config: SimulationConfig,
    traj: Trajectory,
    ambient: _Ambient,
    aircraft: _Aircraft,
    scalar: _Scalar | None,
) -> dict[str, np.ndarray]:
    """Assemble stage: line and maneuver labels and the ``truth_*`` channels."""
    fields: dict[str, np.ndarray] = {
        "line": traj.line.astype(float),
        "maneuver": traj.maneuver.astype(float),
    }
    fields.update(zip(vector_names("truth_earth"), ambient.t_b.T, strict=True))
    fields.update(zip(vector_names("truth_interf"), aircraft.interf.T, strict=True))
    if ambient.crust_n is not None:
        crust_b = nav_to_body(ambient.c_nb, ambient.crust_n)
        fields.update(zip(vector_names("truth_crust"), crust_b.T, strict=True))
    if aircraft.extra is not None:
        fields.update(zip(vector_names("truth_effects"), aircraft.extra.T, strict=True))
    if scalar is not None:
        fields[f"truth_interf_{config.scalar.name.removesuffix('_uc')}"] = scalar.interf
    return fields


def _attributes(
    config: SimulationConfig,
    start: _dt.datetime,
    coefficients: dict[str, dict],
    seed: int | np.integer | None,
    replay: Flight | None,
) -> dict[str, str]:
    """The flight's string attributes: date, configuration, true coefficients, provenance."""
    attrs: dict[str, str] = {
        "date": start.isoformat(),
        "config": to_json(config),
        "truth_coefficients": json.dumps(coefficients, sort_keys=True),
        "maneuver_kinds": ",".join(MANEUVER_KINDS),
        "source": "aeromag_env simulate",
    }
    if seed is not None:
        attrs["seed"] = str(int(seed))
    if replay is not None:
        attrs["replayed_from"] = str(replay.attrs.get("path", "a flight"))
    return attrs


def _replayed_trajectory(flight: Flight) -> Trajectory:
    """The navigation channels of ``flight`` as a :class:`Trajectory` (radians inside)."""
    lat, lon, alt = flight.position_rad()
    roll, pitch, yaw = flight.attitude_rad()
    zeros = np.zeros(flight.n)
    return Trajectory(
        tt=flight.tt.copy(),
        lat=lat,
        lon=lon,
        alt=np.asarray(alt, float),
        roll=roll,
        pitch=pitch,
        yaw=yaw,
        maneuver=flight.maneuver_ids(),
        line=np.nan_to_num(flight["line"]) if "line" in flight else zeros,
    )


def _aux_channels(
    config: SimulationConfig, tt: np.ndarray, replay: Flight | None, rng: np.random.Generator
) -> dict[str, np.ndarray]:
    """Auxiliary channels: the replayed flight's, then the configured simulated ones."""
    aux = {nm: replay[nm].copy() for nm in replay.aux_channels()} if replay is not None else {}
    for cfg, r in zip(config.aux_channels, rng.spawn(len(config.aux_channels)), strict=True):
        if cfg.name in aux:
            raise ConfigError(f"auxiliary channel {cfg.name} is both replayed and simulated")
        aux[cfg.name] = aux_channel(cfg, tt, r)
    return aux


def _navigation_fields(traj: Trajectory, start: _dt.datetime) -> dict[str, np.ndarray]:
    """Time, position, date and attitude channels (degrees at the file boundary)."""
    n = traj.tt.size
    return {
        "tt": traj.tt,
        "lat": np.rad2deg(traj.lat),
        "lon": np.rad2deg(traj.lon),
        "alt": traj.alt,
        "year": np.full(n, float(start.year)),
        "doy": np.full(n, float(start.timetuple().tm_yday)),
        "ins_roll": np.rad2deg(traj.roll),
        "ins_pitch": np.rad2deg(traj.pitch),
        "ins_yaw": np.rad2deg(traj.yaw),
    }
