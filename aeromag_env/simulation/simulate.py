"""Simulate one flight: trajectory → Earth field → aircraft interference → sensors → Flight.

Every stage draws from its own child of the ``rng`` passed in (``rng.spawn``), so changing, say,
the sensor noise leaves the trajectory and the coefficients of the same seed unchanged.
"""

from __future__ import annotations

import datetime as _dt
import json
from collections.abc import Callable

import numpy as np

from aeromag_env.configs import to_json
from aeromag_env.errors import ConfigError
from aeromag_env.flight.data import Flight, vector_names
from aeromag_env.geo import earth
from aeromag_env.geo.earth import external_variation_ned, igrf_ned_along_track, parse_date
from aeromag_env.geo.frames import dcm_from_euler, nav_to_body, time_derivative
from aeromag_env.simulation import trajectory
from aeromag_env.simulation.auxiliary import aux_channel
from aeromag_env.simulation.config import SimulationConfig
from aeromag_env.simulation.effects import EffectContext, simulate_effects
from aeromag_env.simulation.interference import (
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
        variation), ``truth_interf_*`` (interference at the fluxgate) and, with a scalar sensor,
        ``truth_interf_mag_N``; attributes ``date``, ``config`` (JSON), ``seed`` (if given),
        ``truth_coefficients`` (JSON) and ``maneuver_kinds``; all attributes are strings.
    """
    seed = rng if isinstance(rng, (int, np.integer)) else None
    gen = np.random.default_rng(rng)
    r_traj, r_earth, r_coef, r_flux, r_scalar, r_extra = gen.spawn(6)
    r_aux, r_fx = r_extra.spawn(2)
    step = progress or (lambda _stage: None)

    step(STAGES[0])
    if replay is None:
        traj = generate_trajectory(config.trajectory, r_traj)
        dt = 1.0 / config.trajectory.sample_rate_hz
        start = parse_date(config.trajectory.date)
    else:
        traj, start = _replayed_trajectory(replay), replay.date()
        dt = float(np.median(np.diff(traj.tt)))
    aux = _aux_channels(config, traj.tt, replay, r_aux)

    step(STAGES[1])
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
    c_nb = dcm_from_euler(traj.roll, traj.pitch, traj.yaw)
    t_b = nav_to_body(c_nb, earth_n + ext_n)
    tdot_b = time_derivative(t_b, traj.tt, "central")

    step(STAGES[2])
    coef = draw_coefficients(config.interference, r_coef)
    interf = vector_interference(coef, t_b, tdot_b)
    extra = None
    if config.effects:
        ctx = EffectContext(
            tt=traj.tt, c_nb=c_nb, t_b=t_b, tdot_b=tdot_b,
            t2dot_b=time_derivative(tdot_b, traj.tt, "central"), alt=traj.alt, aux=aux,
            signal=t_b + interf, rng=r_fx, start=start,
        )  # fmt: skip
        extra = simulate_effects(ctx, config.effects)

    step(STAGES[3])
    flux = t_b + interf + sensor_noise(traj.tt.size, dt, config.fluxgate_noise, r_flux)
    if extra is not None:
        flux += extra
    fields = _navigation_fields(traj, start)
    fields.update(aux)
    fields.update(zip(vector_names(config.fluxgate), flux.T, strict=True))
    coefficients: dict[str, dict] = {config.fluxgate: coef.to_dict()}
    scalar = config.scalar
    if scalar.enabled:
        coef_s = draw_coefficients(scalar.interference, r_scalar)
        interf_s = scalar_interference(coef_s, t_b, tdot_b)
        noise_s = sensor_noise(traj.tt.size, dt, scalar.noise, r_scalar, dims=1)
        fields[scalar.name] = np.linalg.norm(t_b, axis=1) + interf_s + noise_s
        coefficients[scalar.name] = {
            **coef_s.to_dict(),
            "tolles_lawson": coefficients_from_vector(coef_s, dt).tolist(),
        }
    if replay is not None and "diurnal" in replay:
        fields["diurnal"] = replay["diurnal"].copy()
    elif config.earth.daily_amplitude_nt > 0 or config.earth.external_fogm_std_nt > 0:
        # a base-station total-field magnetometer sees the projection on the main-field direction
        unit = earth_n / np.linalg.norm(earth_n, axis=1, keepdims=True)
        fields["diurnal"] = np.sum(unit * ext_n, axis=1)

    step(STAGES[4])
    fields["line"] = traj.line.astype(float)
    fields["maneuver"] = traj.maneuver.astype(float)
    fields.update(zip(vector_names("truth_earth"), t_b.T, strict=True))
    fields.update(zip(vector_names("truth_interf"), interf.T, strict=True))
    if extra is not None:
        fields.update(zip(vector_names("truth_effects"), extra.T, strict=True))
    if scalar.enabled:
        fields[f"truth_interf_{scalar.name.removesuffix('_uc')}"] = interf_s
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
    return Flight(
        fields={k: np.ascontiguousarray(v, float) for k, v in fields.items()}, attrs=attrs
    )


def _replayed_trajectory(flight: Flight) -> Trajectory:
    """The navigation channels of ``flight`` as a :class:`Trajectory` (radians inside)."""
    lat, lon, alt = flight.position_rad()
    roll, pitch, yaw = flight.attitude_rad()
    zeros = np.zeros(flight.n)
    return Trajectory(
        tt=flight.tt.copy(), lat=lat, lon=lon, alt=np.asarray(alt, float), roll=roll,
        pitch=pitch, yaw=yaw,
        maneuver=np.nan_to_num(flight["maneuver"]).astype(int) if "maneuver" in flight else zeros,
        line=np.nan_to_num(flight["line"]) if "line" in flight else zeros,
    )  # fmt: skip


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
