"""Crustal anomaly: the potential-field physics of :mod:`aeromag_env.geo.crust` (curl- and
divergence-free, upward continuation, Riesz/Hilbert pair, a buried dipole in closed form, RMS
against the spectrum's integral), its along-track evaluation against the exact Fourier series,
its configuration, and its place in the simulated flight."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import quad
from scipy.signal import hilbert

from aeromag_env.configs import from_dict, from_json, to_json
from aeromag_env.errors import ConfigError
from aeromag_env.flight.data import Flight
from aeromag_env.geo import crust as cr
from aeromag_env.geo import crust_area
from aeromag_env.geo.frames import body_to_nav, dcm_from_euler
from aeromag_env.simulation.config import (
    PRESETS,
    GeologyConfig,
    SimulationConfig,
    preset,
    with_overrides,
)
from aeromag_env.simulation.simulate import simulate_flight
from tests._helpers import assert_one_line_error

SPECTRUM = {"depth_to_source_m": 200.0, "source_thickness_m": 3000.0, "fractal_exponent": 2.0}
LAT0, LON0 = np.deg2rad(45.3), np.deg2rad(-76.0)


def _track(n: int = 60) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A 10 km line north, half at 400 m and half at 3000 m (the altitudes of a survey)."""
    lat = LAT0 + np.linspace(0.0, 10_000.0 / 6.37e6, n)
    return lat, np.full(n, LON0), np.r_[np.full(n // 2, 400.0), np.full(n - n // 2, 3000.0)]


def _crust(seed: int = 1, main_field_ned: np.ndarray | None = None) -> cr.CrustField:
    rng = np.random.default_rng(seed)
    return cr.random_crust(
        *_track(),
        rng,
        rms_nt=50.0,
        reference_altitude_m=400.0,
        main_field_ned=main_field_ned,
        **SPECTRUM,
    )


def _rel_rms(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.sqrt(np.mean((a - b) ** 2) / np.mean(b**2)))


def test_curl_and_divergence_vanish_on_the_grid():
    """∂B_n/∂e = ∂B_e/∂n, ∂B_n/∂z = ∂B_d/∂n and ∇·B = 0 by finite differences (z down = −h).
    Central differences err by ~(kΔ)²/6 at the field's wavenumbers k ~ 1/(h + d): ≲ 1 % at
    1000 m with Δ = 120 m; a wrong sign on any component would leave 100–200 %."""
    crust, h, dh = _crust(), 1000.0, 5.0
    b_n, b_e, b_d = cr.field_grid(crust, h)
    above, below = cr.field_grid(crust, h + dh), cr.field_grid(crust, h - dh)
    d_dz = -(above - below) / (2 * dh)  # ∂/∂z = −∂/∂h
    d_dn = [np.gradient(c, crust.spacing_m, axis=0)[2:-2, 2:-2] for c in (b_n, b_e, b_d)]
    d_de = [np.gradient(c, crust.spacing_m, axis=1)[2:-2, 2:-2] for c in (b_n, b_e, b_d)]
    inner = d_dz[:, 2:-2, 2:-2]
    assert _rel_rms(d_de[0], d_dn[1]) < 0.02
    assert _rel_rms(inner[0], d_dn[2]) < 0.02
    assert _rel_rms(inner[1], d_de[2]) < 0.02
    divergence = d_dn[0] + d_de[1] + inner[2]
    assert np.sqrt(np.mean(divergence**2)) < 0.02 * np.sqrt(np.mean(inner[2] ** 2))


def test_field_at_h2_is_field_at_h1_continued_upwards():
    """Each component at 1500 m equals the 400 m grid continued by exp(−|k| Δh), with an
    independent full complex FFT (not the module's real transforms); to round-off."""
    crust = _crust()
    low, high = cr.field_grid(crust, 400.0), cr.field_grid(crust, 1500.0)
    k_n = 2 * np.pi * np.fft.fftfreq(crust.shape[0], crust.spacing_m)[:, None]
    k_e = 2 * np.pi * np.fft.fftfreq(crust.shape[1], crust.spacing_m)[None, :]
    up = np.exp(-np.hypot(k_n, k_e) * 1100.0)
    continued = np.fft.ifft2(np.fft.fft2(low) * up).real
    np.testing.assert_allclose(continued, high, atol=1e-9 * np.abs(high).max())


def test_buried_dipole_matches_its_closed_form():
    """Given only the down component of an inclined dipole 1 km deep at the ground, the module
    gives all three components at 0 and 600 m and along a track, as ``B = C (3 (m·R̂) R̂ − m) /
    |R|³`` does. Tolerance 1 % of the peak: the periodic images 40 km away add ~(1/20)³."""
    spacing, size, depth = 100.0, 400, 1000.0
    moment = np.array([0.4, -0.3, 0.87])

    def dipole(n: np.ndarray, e: np.ndarray, h: np.ndarray) -> np.ndarray:
        r = np.stack([n, e, -h - depth], axis=-1)  # NED from the dipole at z = +depth
        dist = np.linalg.norm(r, axis=-1, keepdims=True)
        unit = r / dist
        return 1e12 * (3 * np.sum(moment * unit, -1, keepdims=True) * unit - moment) / dist**3

    axis = -size / 2 * spacing + spacing * np.arange(size)
    n, e = np.meshgrid(axis, axis, indexing="ij")
    ground = dipole(n, e, np.zeros_like(n))
    crust = cr.CrustField(
        spectrum=np.fft.rfft2(ground[..., 2]),
        shape=(size, size),
        spacing_m=spacing,
        origin_m=(axis[0], axis[0]),
        lat0_rad=LAT0,
        lon0_rad=LON0,
        depth_to_source_m=depth,
    )
    for h in (0.0, 600.0):
        truth = np.moveaxis(dipole(n, e, np.full_like(n, h)), -1, 0)
        assert np.abs(cr.field_grid(crust, h) - truth).max() < 0.01 * np.abs(truth).max()
    pts = np.random.default_rng(0).uniform(-3000.0, 3000.0, (2, 200))
    alt = np.random.default_rng(1).uniform(300.0, 2000.0, 200)
    truth = dipole(pts[0], pts[1], alt)
    assert (
        np.abs(cr.field_at(crust, pts[0], pts[1], alt) - truth).max() < 0.01 * np.abs(truth).max()
    )


def test_horizontal_and_vertical_are_a_hilbert_pair():
    """For a field varying along north only, B_e = 0 and B_n = −H[B_d] (H the Hilbert transform,
    ``scipy.signal.hilbert``); for any field, the Riesz pair keeps B_n² + B_e² = B_d² on average."""
    profile = np.random.default_rng(3).standard_normal(512)
    grid = np.tile(profile[:, None], (1, 8))
    crust = cr.CrustField(
        spectrum=np.fft.rfft2(grid),
        shape=grid.shape,
        spacing_m=100.0,
        origin_m=(0.0, 0.0),
        lat0_rad=LAT0,
        lon0_rad=LON0,
        depth_to_source_m=100.0,
    )
    b_n, b_e, b_d = cr.field_grid(crust, 300.0)
    assert np.abs(b_e).max() < 1e-12 * np.abs(b_d).max()
    np.testing.assert_allclose(b_n[:, 0], -np.imag(hilbert(b_d[:, 0])), atol=1e-4 * b_d.std())
    crust = _crust()
    for h in (400.0, 3000.0):
        b_n, b_e, b_d = cr.field_grid(crust, h)
        np.testing.assert_allclose(np.mean(b_n**2 + b_e**2), np.mean(b_d**2), rtol=1e-6)


def test_rms_at_the_reference_and_its_fall_with_altitude():
    """The total-field anomaly has the configured RMS at the reference altitude (exactly), and
    its RMS falls with altitude as ``∫ P(k) exp(−2kh) k dk`` (quadrature of the continuous
    spectrum) says. Over 4 draws: the draw-to-draw scatter is ~2 % at 1000 m and ~4 % at 3000 m
    and the grid lacks wavelengths beyond its span (~2-4 % low at 3000 m), hence 5 % and 10 %."""
    direction = np.array([0.3, -0.1, 0.95])
    unit = direction / np.linalg.norm(direction)
    ratios = []
    for seed in range(4):
        crust = _crust(seed, direction)
        tmi = {h: np.tensordot(unit, cr.field_grid(crust, h), 1) for h in (400.0, 1000.0, 3000.0)}
        np.testing.assert_allclose(np.sqrt(np.mean(tmi[400.0] ** 2)), 50.0, rtol=1e-12)
        ratios.append([np.sqrt(np.mean(tmi[h] ** 2)) / 50.0 for h in (1000.0, 3000.0)])

    def power(h: float) -> float:
        return quad(
            lambda k: cr.source_spectrum(np.array(k), **SPECTRUM) * np.exp(-2 * k * h) * k,
            0,
            np.inf,
            limit=500,
        )[0]

    expected = [np.sqrt(power(h) / power(400.0)) for h in (1000.0, 3000.0)]
    assert 0.3 < expected[1] < 0.5 < expected[0] < 0.9  # the fall is large: the test can fail
    found = np.mean(ratios, axis=0)
    np.testing.assert_allclose(found[0], expected[0], rtol=0.05)
    np.testing.assert_allclose(found[1], expected[1], rtol=0.10)


def test_along_track_evaluation_matches_the_exact_fourier_series():
    """Splines across and cubic Hermite in altitude against the direct sum of the Fourier series
    at 40 points between 400 and 3000 m: within 0.05 nT of a 50 nT RMS field."""
    crust = _crust()
    rng = np.random.default_rng(7)
    north, east = rng.uniform(0.0, 10_000.0, 40), rng.uniform(-500.0, 500.0, 40)
    alt = rng.uniform(400.0, 3000.0, 40)
    k_n, k_e, _ = crust.wavenumbers()
    weight = np.full(k_e.shape, 2.0)  # the half spectrum stands for its mirror too
    weight[0, 0] = 1.0
    weight[0, -1] = 1.0 if crust.shape[1] % 2 == 0 else 2.0
    exact = np.empty((40, 3))
    for i in range(40):
        phase = np.exp(
            1j * (k_n * (north[i] - crust.origin_m[0]) + k_e * (east[i] - crust.origin_m[1]))
        )
        spectra = cr.component_spectra(crust, alt[i])
        exact[i] = np.real(np.sum(spectra * phase * weight, axis=(1, 2))) / np.prod(crust.shape)
    assert np.abs(exact).max() > 20.0  # a field worth comparing
    np.testing.assert_allclose(cr.field_at(crust, north, east, alt), exact, atol=0.05)


def test_same_seed_same_ground_and_position_only():
    a, b, c = _crust(5), _crust(5), _crust(6)
    np.testing.assert_array_equal(a.spectrum, b.spectrum)
    assert not np.allclose(a.spectrum, c.spectrum)
    lat, lon, alt = _track()
    once = cr.field_at_positions(a, lat, lon, alt)
    reversed_ = cr.field_at_positions(a, lat[::-1], lon[::-1], alt[::-1])[::-1]
    np.testing.assert_allclose(once, reversed_, atol=1e-9)  # the same place, the same vector


def test_tracks_the_grid_cannot_serve_are_refused():
    lat, lon, alt = _track()
    with pytest.raises(ValueError, match="below the crustal sources' top"):
        cr.random_crust(
            lat,
            lon,
            alt - 700.0,
            np.random.default_rng(0),
            rms_nt=50.0,
            reference_altitude_m=400.0,
            **SPECTRUM,
        )
    wide = np.linspace(0.0, np.deg2rad(10.0), lat.size)  # 10⁷ nodes at 120 m
    with pytest.raises(
        ValueError, match="spans 1121 km × 784 km: too large for a crustal grid down to 400 m"
    ):
        cr.random_crust(
            lat + wide,
            lon + wide,
            alt,
            np.random.default_rng(0),
            rms_nt=50.0,
            reference_altitude_m=400.0,
            **SPECTRUM,
        )


@pytest.mark.parametrize(
    ("field", "value", "words"),
    [
        ("rms_nt", -1.0, "GeologyConfig.rms_nt must be ≥ 0"),
        ("rms_nt", float("nan"), "GeologyConfig.rms_nt must be ≥ 0"),
        ("depth_to_source_m", 0.0, "GeologyConfig.depth_to_source_m must be > 0"),
        ("source_thickness_m", float("inf"), "GeologyConfig.source_thickness_m must be > 0"),
        ("reference_altitude_m", -5.0, "GeologyConfig.reference_altitude_m must be ≥ 0"),
        ("fractal_exponent", 4.0, r"GeologyConfig.fractal_exponent must be in \[0, 4\)"),
        ("seed", -1, "GeologyConfig.seed must be ≥ 0"),
    ],
)
def test_geology_config_errors_are_one_line(field, value, words):
    with pytest.raises(ConfigError, match=words) as err:
        GeologyConfig(**{field: value})
    assert_one_line_error(err)


def test_geology_config_round_trip_and_overrides():
    assert all(PRESETS[name]().geology is None for name in PRESETS)  # off in every preset
    cfg = with_overrides(preset("paper"), {"geology": {"rms_nt": 80, "seed": 3}})
    assert cfg.geology == GeologyConfig(rms_nt=80.0, seed=3)
    assert from_json(SimulationConfig, to_json(cfg)) == cfg
    assert with_overrides(cfg, {"geology.depth_to_source_m": 500}).geology.depth_to_source_m == 500
    with pytest.raises(ConfigError, match=r"GeologyConfig: unknown field\(s\) rms"):
        from_dict(SimulationConfig, {"geology": {"rms": 1}})


def _flight(name: str, seed: int, geology: GeologyConfig | None, **trajectory) -> Flight:
    cfg = preset(name)
    cfg = dataclasses.replace(
        cfg, trajectory=dataclasses.replace(cfg.trajectory, **trajectory), geology=geology
    )
    return simulate_flight(cfg, seed)


@pytest.mark.parametrize("name", ["nominal", "paper"])
def test_a_silent_ground_leaves_every_field_bit_identical(name):
    """With a crustal field of 0 nT every field equals the flight without geology bit for bit:
    drawing the ground takes nothing from the other stages' random streams."""
    off = _flight(name, 4, None, duration_s=300.0)
    silent = _flight(name, 4, GeologyConfig(rms_nt=0.0), duration_s=300.0)
    assert set(silent.names) - set(off.names) == {"truth_crust_x", "truth_crust_y", "truth_crust_z"}
    for k in off.names:
        assert np.array_equal(off[k], silent[k]), k
    assert not np.any(silent.vector("truth_crust"))


def test_the_ground_reaches_every_sensor_and_nothing_else():
    """A 50 nT ground changes the ambient field by exactly ``truth_crust`` and the scalar reading
    by its total-field part (to 0.2 nT: the scalar's own induced field, ~5e-4 × 50 nT, and the
    second-order term |B_c|²/2|T| ≈ 0.03 nT), and leaves trajectory, diurnal, coefficients and
    noise untouched."""
    off = _flight("nominal", 9, None, duration_s=600.0)
    on = _flight("nominal", 9, GeologyConfig(), duration_s=600.0)
    crust_b = on.vector("truth_crust")
    assert np.sqrt(np.mean(crust_b**2)) > 5.0
    for k in ("lat", "lon", "alt", "ins_roll", "ins_yaw", "diurnal", "line"):
        assert np.array_equal(off[k], on[k]), k
    assert on.attrs["truth_coefficients"] == off.attrs["truth_coefficients"]
    np.testing.assert_allclose(
        on.vector("truth_earth") - crust_b, off.vector("truth_earth"), atol=1e-9
    )
    noise = [
        f.vector("flux_a") - f.vector("truth_earth") - f.vector("truth_interf") for f in (on, off)
    ]
    np.testing.assert_allclose(noise[0], noise[1], atol=1e-9)
    earth = off.vector("truth_earth")
    tmi = np.sum(earth / np.linalg.norm(earth, axis=1, keepdims=True) * crust_b, axis=1)
    np.testing.assert_allclose(on["mag_1_uc"] - off["mag_1_uc"], tmi, atol=0.2)


def _crossing_flight(seed: int) -> Flight:
    """A line north then a line east through the same point (sample 100 of each), replayed."""
    n = 201
    d_lat, d_lon = np.deg2rad(0.05), np.deg2rad(0.07)
    lat = np.r_[LAT0 + np.linspace(-d_lat, d_lat, n), np.full(n, LAT0)]
    lon = np.r_[np.full(n, LON0), LON0 + np.linspace(-d_lon, d_lon, n)]
    fields = {
        "tt": np.arange(2 * n) * 0.1,
        "lat": np.rad2deg(lat),
        "lon": np.rad2deg(lon),
        "alt": np.full(2 * n, 400.0),
        "ins_roll": np.r_[np.full(n, 3.0), np.full(n, -4.0)],
        "ins_pitch": np.full(2 * n, 1.0),
        "ins_yaw": np.r_[np.zeros(n), np.full(n, 90.0)],
    }
    replay = Flight(fields=fields, attrs={"date": "2026-06-01T14:00:00"})
    cfg = dataclasses.replace(preset("paper"), geology=GeologyConfig(seed=21))
    return simulate_flight(cfg, seed, replay=replay)


def test_a_tie_line_sees_the_survey_line_vector_at_the_crossing():
    """The crustal field depends on position only: at the crossing the NED vector is the same
    on both lines (the body-frame one differs, the heading does), and a flight of another seed
    over the same configured ground (``GeologyConfig.seed``) sees the same field."""
    flights = [_crossing_flight(seed) for seed in (1, 2)]
    ned = [body_to_nav(dcm_from_euler(*f.attitude_rad()), f.vector("truth_crust")) for f in flights]
    crossing = [100, 301]
    np.testing.assert_allclose(ned[0][crossing[0]], ned[0][crossing[1]], atol=1e-9)
    assert np.abs(ned[0][crossing[0]]).max() > 1.0
    body = flights[0].vector("truth_crust")
    assert np.abs(body[crossing[0]] - body[crossing[1]]).max() > 1.0
    np.testing.assert_allclose(ned[0], ned[1], atol=1e-9)


def test_the_box_at_3000_m_sees_much_less_ground_than_the_lines_at_400_m():
    """Along a calibration box (3000 m) then survey lines (400 m), the crustal field's RMS falls
    as its spectrum says (to 0.39 of the 400 m value for the defaults; the box samples only a
    few km of ground, so the bound is loose)."""
    f = _flight("nominal", 2, GeologyConfig(), pattern="calibration+survey", duration_s=2400.0)
    crust = f.vector("truth_crust")
    box, lines = f["line"] == 1, f["line"] >= 1001
    assert np.all(f["alt"][box] > 2900) and np.all(f["alt"][lines] < 500)
    rms = [np.sqrt(np.mean(np.sum(crust[sel] ** 2, axis=1))) for sel in (box, lines)]
    assert rms[1] > 20.0
    assert 0.15 < rms[0] / rms[1] < 0.65


# The ground of an area (``GeologyConfig.seed`` set): aeromag_env.geo.crust_area.


def _ned_crust(f: Flight) -> np.ndarray:
    return body_to_nav(dcm_from_euler(*f.attitude_rad()), f.vector("truth_crust"))


def _exact(crust: cr.CrustField, north: np.ndarray, east: np.ndarray, alt: np.ndarray):
    """The crustal field at local positions by the direct sum of its Fourier series (n, 3) [nT]."""
    k_n, k_e, _ = crust.wavenumbers()
    weight = np.full(k_e.shape, 2.0)  # the half spectrum stands for its mirror too
    weight[0, 0] = 1.0
    weight[0, -1] = 1.0 if crust.shape[1] % 2 == 0 else 2.0
    exact = np.empty((north.size, 3))
    for i in range(north.size):
        phase = np.exp(
            1j * (k_n * (north[i] - crust.origin_m[0]) + k_e * (east[i] - crust.origin_m[1]))
        )
        spectra = cr.component_spectra(crust, alt[i])
        exact[i] = np.real(np.sum(spectra * phase * weight, axis=(1, 2))) / np.prod(crust.shape)
    return exact


AREA = GeologyConfig(seed=7)


def test_flights_of_other_patterns_lengths_and_seeds_see_the_same_ground():
    """A calibration+survey flight (nominal, seed 1, 20 min) and a replay of part of its survey
    lines backwards (paper, seed 2, other attitude): both get the area's ground, so the replay
    sees the first flight's NED vector at every one of its positions — to round-off, since the
    grid and the altitude levels come from the configuration alone (a grid around each track
    would give two different grounds, tens of nT apart)."""
    first = _flight("nominal", 1, AREA, pattern="calibration+survey", duration_s=1200.0)
    lines = np.flatnonzero(first["line"] >= 1001)[::-1][:2000]  # backwards along the lines
    assert lines.size == 2000 and np.ptp(first["alt"]) > 2000  # box and lines, lines only
    fields = {
        "tt": np.arange(lines.size) * 0.1,
        "lat": first["lat"][lines],
        "lon": first["lon"][lines],
        "alt": first["alt"][lines],
        "ins_roll": np.full(lines.size, 5.0),
        "ins_pitch": np.full(lines.size, -2.0),
        "ins_yaw": np.full(lines.size, 30.0),
    }
    replay = Flight(fields=fields, attrs={"date": "2027-03-01T09:00:00"})
    second = simulate_flight(dataclasses.replace(preset("paper"), geology=AREA), 2, replay=replay)
    seen = _ned_crust(second)
    assert np.sqrt(np.mean(seen**2)) > 10.0  # a ground worth comparing
    np.testing.assert_allclose(seen, _ned_crust(first)[lines], atol=1e-9)


@pytest.mark.slow
def test_each_flight_samples_the_areas_exact_fourier_series():
    """A survey flight and a calibration+survey flight of other lengths and seeds: at 12 samples
    of each (box at 3000 m and lines at 400 m) the NED vector is the area ground's exact
    Fourier series, within the evaluation's tested 0.05 nT."""
    flights = [
        _flight("nominal", 3, AREA, pattern="survey", duration_s=900.0),
        _flight("paper", 4, AREA, pattern="calibration+survey", duration_s=1500.0),
    ]
    center = (AREA.area_center_lat_deg or 45.3, AREA.area_center_lon_deg or -76.0)
    ground = crust_area.area_ground(
        7, center, 100.0, 300.0, rms_nt=50.0, reference_altitude_m=400.0, **SPECTRUM
    )
    for f in flights:
        pick = np.linspace(0, f.n - 1, 12).astype(int)
        north, east = cr.local_north_east(
            np.deg2rad(f["lat"][pick]),
            np.deg2rad(f["lon"][pick]),
            ground.crust.lat0_rad,
            ground.crust.lon0_rad,
        )
        exact = _exact(ground.crust, north, east, f["alt"][pick])
        assert np.abs(exact).max() > 10.0
        np.testing.assert_allclose(_ned_crust(f)[pick], exact, atol=0.05)


def test_the_areas_fixed_levels_match_the_exact_fourier_series():
    """Splines across and Hermite between the levels anchored at ``min_altitude_m`` (not at the
    points' own altitudes): within 0.05 nT at 40 points from 300 to 3000 m, as for a track's
    grid; the levels of two altitude ranges coincide where they overlap."""
    ground = crust_area.area_ground(
        3, (45.3, -76.0), 10.0, 300.0, rms_nt=50.0, reference_altitude_m=400.0, **SPECTRUM
    )
    rng = np.random.default_rng(11)
    north, east = rng.uniform(-5000.0, 5000.0, (2, 40))
    alt = rng.uniform(300.0, 3000.0, 40)
    exact = _exact(ground.crust, north, east, alt)
    assert np.abs(exact).max() > 20.0
    np.testing.assert_allclose(cr.field_at(ground.crust, north, east, alt), exact, atol=0.05)
    low, wide = cr._levels(400.0, 400.0, 200.0, 300.0), cr._levels(350.0, 3000.0, 200.0, 300.0)
    np.testing.assert_array_equal(low, wide[:2])
    np.testing.assert_allclose(wide[[0, -1]], [300.0, 500 * 1.5**5 - 200])


def test_a_seeded_ground_is_drawn_once_for_many_flights():
    crust_area.area_ground.cache_clear()
    for seed in (1, 2):
        _flight("nominal", seed, GeologyConfig(seed=5), pattern="survey", duration_s=60.0)
    info = crust_area.area_ground.cache_info()
    assert (info.misses, info.hits) == (1, 1)


@pytest.mark.parametrize(
    ("geology", "trajectory", "words"),
    [
        (
            GeologyConfig(seed=1, area_size_km=10.0),
            {"pattern": "survey", "duration_s": 300.0},
            r"the track leaves the 10 km geology area around \(45.3000°, -76.0000°\) by 6\.03 km: "
            "set GeologyConfig.area_size_km or area_center_lat_deg/area_center_lon_deg",
        ),
        (
            GeologyConfig(seed=1, area_center_lat_deg=46.0, area_center_lon_deg=-76.0),
            {"pattern": "survey", "duration_s": 60.0},
            "leaves the 100 km geology area around "
            r"\(46\.0000°, -76\.0000°\) by 2[78]\.\d\d km",
        ),
        (
            GeologyConfig(seed=1, min_altitude_m=500.0),
            {"pattern": "survey", "duration_s": 60.0},
            "the track flies down to 400 m, below GeologyConfig.min_altitude_m = 500 m",
        ),
    ],
)
def test_a_track_the_area_does_not_serve_is_refused(geology, trajectory, words):
    with pytest.raises(ValueError, match=words) as err:
        _flight("nominal", 0, geology, **trajectory)
    assert_one_line_error(err)


@pytest.mark.parametrize(
    ("fields", "words"),
    [
        ({"area_center_lat_deg": 45.0}, "area_center_lon_deg must be both set or both None"),
        ({"area_center_lat_deg": 95.0, "area_center_lon_deg": 0.0}, r"must be in \(-90, 90\)"),
        ({"area_center_lat_deg": 0.0, "area_center_lon_deg": 400.0}, "out of range: 400.0"),
        ({"area_size_km": 0.0}, "GeologyConfig.area_size_km must be > 0"),
        ({"min_altitude_m": float("nan")}, "GeologyConfig.min_altitude_m must be ≥ 0"),
        (
            {"area_size_km": 300.0},
            "GeologyConfig.area_size_km: a 300 km area down to 300 m "
            r"needs 3200 × 3200 crustal grid nodes at 100 m, more than 4194304",
        ),
    ],
)
def test_geology_area_errors_are_one_line(fields, words):
    with pytest.raises(ConfigError, match=words) as err:
        GeologyConfig(**fields)
    assert_one_line_error(err)


def test_geology_area_round_trip():
    cfg = with_overrides(
        preset("paper"),
        {"geology": {"seed": 3, "area_center_lat_deg": 50.0, "area_center_lon_deg": 10.0}},
    )
    assert from_json(SimulationConfig, to_json(cfg)) == cfg


def test_cli_refuses_a_track_off_the_geology_area_in_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A configuration error, not an internal one: exit 2, one line, no file written."""
    from aeromag_env.cli.main import main
    from aeromag_env.simulation.config import preset, with_overrides

    cfg = with_overrides(preset("nominal"), {"geology": {"seed": 3, "area_size_km": 5.0}})
    path = tmp_path / "small_area.json"
    path.write_text(to_json(cfg))
    assert main(["simulate", "--config", str(path), "--out", str(tmp_path / "f.h5")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "error: the track leaves the 5 km geology area" in err[0]
    assert "internal error" not in err[0] and not (tmp_path / "f.h5").exists()
