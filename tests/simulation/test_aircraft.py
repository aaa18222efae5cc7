"""One aircraft, many flights: the aircraft's seed draws its interference, the flight's the rest."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from aeromag_env.errors import ConfigError
from aeromag_env.simulation.config import AircraftConfig, preset, with_overrides
from aeromag_env.simulation.simulate import simulate_flight
from tests._helpers import assert_one_line_error

SHORT = with_overrides(preset("nominal"), {"trajectory.duration_s": 60.0})


def _coefficients(aircraft: AircraftConfig | None, seed: int) -> dict:
    flight = simulate_flight(dataclasses.replace(SHORT, aircraft=aircraft), seed)
    return json.loads(flight.attrs["truth_coefficients"])


def test_one_aircraft_keeps_its_coefficients_across_flight_seeds():
    a, b = _coefficients(AircraftConfig(seed=5), 1), _coefficients(AircraftConfig(seed=5), 2)
    assert a == b
    assert a != _coefficients(AircraftConfig(seed=6), 1)


def test_without_an_aircraft_the_flight_seed_draws_the_coefficients_as_before():
    # the flight's own children draw them (unchanged from before the aircraft existed)
    assert _coefficients(None, 1) != _coefficients(None, 2)
    flight = simulate_flight(SHORT, 1)
    again = simulate_flight(dataclasses.replace(SHORT, aircraft=None), 1)
    np.testing.assert_array_equal(flight["mag_1_uc"], again["mag_1_uc"])


def test_the_flight_seed_still_draws_the_noise():
    plane = dataclasses.replace(SHORT, aircraft=AircraftConfig(seed=5))
    f1, f2 = simulate_flight(plane, 1), simulate_flight(plane, 2)
    assert not np.allclose(f1["flux_a_x"], f2["flux_a_x"])


def test_maintenance_shifts_the_permanent_field_exactly():
    shift, scalar_shift = (10.0, -20.0, 30.0), (1.0, 2.0, -3.0)
    before = _coefficients(AircraftConfig(seed=5), 1)
    after = _coefficients(
        AircraftConfig(seed=5, permanent_shift_nt=shift, scalar_permanent_shift_nt=scalar_shift), 1
    )
    np.testing.assert_allclose(  # 1e-12 nT: one addition of doubles
        np.subtract(after["flux_a"]["permanent_nt"], before["flux_a"]["permanent_nt"]),
        shift,
        atol=1e-12,
    )
    np.testing.assert_allclose(
        np.subtract(after["mag_1_uc"]["permanent_nt"], before["mag_1_uc"]["permanent_nt"]),
        scalar_shift,
        atol=1e-12,
    )
    assert after["flux_a"]["induced"] == before["flux_a"]["induced"]
    assert AircraftConfig(seed=1, permanent_shift_nt=shift).maintained


@pytest.mark.parametrize(
    ("kwargs", "word"),
    [({"seed": -1}, "seed"), ({"seed": 1, "permanent_shift_nt": (1.0, 2.0)}, "permanent_shift_nt")],
)
def test_bad_aircraft_settings_are_one_line_errors(kwargs, word):
    with pytest.raises(ConfigError) as e:
        AircraftConfig(**kwargs)
    assert_one_line_error(e, word)


def test_aircraft_round_trips_through_the_flight_config():
    cfg = with_overrides(
        dataclasses.replace(SHORT, aircraft=AircraftConfig(seed=3)), {"aircraft.seed": 4}
    )
    assert cfg.aircraft == AircraftConfig(seed=4)
