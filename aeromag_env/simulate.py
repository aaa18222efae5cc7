"""Simulate one flight: trajectory → Earth field → aircraft interference → sensors → Flight.

Every stage draws from its own child of the ``rng`` passed in (``rng.spawn``), so changing, say,
the sensor noise leaves the trajectory and the coefficients of the same seed unchanged.
"""

from __future__ import annotations

import datetime as _dt
import json
from collections.abc import Callable

import numpy as np

from aeromag_env.config import SimulationConfig, to_json
from aeromag_env.earth import external_variation_ned, igrf_ned_along_track, parse_date
from aeromag_env.flight import Flight, vector_names
from aeromag_env.frames import dcm_from_euler, nav_to_body, time_derivative
from aeromag_env.interference import draw_coefficients, scalar_interference, vector_interference
from aeromag_env.sensors import sensor_noise
from aeromag_env.tolles_lawson import coefficients_from_vector
from aeromag_env.trajectory import MANEUVER_KINDS, Trajectory, generate_trajectory

#: Simulation stages, in order, as reported to a progress callback.
STAGES = ("trajectory", "earth field", "interference", "sensors", "assemble")


def simulate_flight(
    config: SimulationConfig,
    rng: np.random.Generator | int,
    progress: Callable[[str], None] | None = None,
) -> Flight:
    """Simulate one flight.

    Parameters
    ----------
    config : SimulationConfig
    rng : numpy.random.Generator or int
        Source of every random draw; an int is used as the seed (and recorded in the file).
    progress : callable, optional
        Called with each stage name of :data:`STAGES` as it starts.

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
    r_traj, r_earth, r_coef, r_flux, r_scalar = gen.spawn(5)
    step = progress or (lambda _stage: None)

    step(STAGES[0])
    traj = generate_trajectory(config.trajectory, r_traj)
    dt = 1.0 / config.trajectory.sample_rate_hz
    start = parse_date(config.trajectory.date)

    step(STAGES[1])
    earth_n = igrf_ned_along_track(
        traj.tt, traj.lat, traj.lon, traj.alt, start, config.earth.igrf_grid_spacing_s
    )
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

    step(STAGES[3])
    flux = t_b + interf + sensor_noise(traj.tt.size, dt, config.fluxgate_noise, r_flux)
    fields = _navigation_fields(traj, start)
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
    if config.earth.daily_amplitude_nt > 0 or config.earth.external_fogm_std_nt > 0:
        # a base-station total-field magnetometer sees the projection on the main-field direction
        unit = earth_n / np.linalg.norm(earth_n, axis=1, keepdims=True)
        fields["diurnal"] = np.sum(unit * ext_n, axis=1)

    step(STAGES[4])
    fields["line"] = traj.line.astype(float)
    fields["maneuver"] = traj.maneuver.astype(float)
    fields.update(zip(vector_names("truth_earth"), t_b.T, strict=True))
    fields.update(zip(vector_names("truth_interf"), interf.T, strict=True))
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
    return Flight(
        fields={k: np.ascontiguousarray(v, float) for k, v in fields.items()}, attrs=attrs
    )


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
