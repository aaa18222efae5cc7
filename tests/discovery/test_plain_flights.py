"""False alarms on plain flights (``aeromag_env.discovery.plain_flights``): the committed
``docs/discovery/nominal.md`` is what the committed rows give, the cases go round the presets and
durations, and the field the base model lacks is the external variation across the main field
and nothing else. The flights themselves run, test-sized, in ``tests/test_experiments.py``
(``experiments/discovery_nominal.py --quick``, marked slow)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from aeromag_env.discovery.plain_flights import (
    DURATIONS_S,
    SEED0,
    plain_cases,
    plain_summary,
    unmodelled_external,
)
from aeromag_env.simulation.config import preset, with_overrides
from aeromag_env.simulation.simulate import simulate_flight

DISCOVERY = Path(__file__).resolve().parents[2] / "docs" / "discovery"


def test_the_committed_nominal_md_is_what_the_committed_rows_give():
    rows = json.loads((DISCOVERY / "nominal.json").read_text())
    assert plain_summary(rows) == (DISCOVERY / "nominal.md").read_text()


def test_a_refused_flight_is_counted_and_left_out_of_the_rates():
    row = {"preset": "paper", "seed": 1, "duration_s": 1500.0, "named": [], "snr": 0.0}
    rows = [
        {**row, "false_alarm": False, "seconds": 10.0},
        {**row, "named": ["sensor_lag"], "false_alarm": True, "seconds": 20.0},
        {"preset": "nominal", "seed": 2, "duration_s": 1500.0, "error": "refused"},
    ]
    text = plain_summary(rows)
    assert "* flights: 3 (nominal 1, paper 2, noise_free 0); refused: 1\n" in text
    assert "false alarms (an effect the flight does not carry): 1/2 = 50%" in text
    assert "median 36.0 s per flight-hour" in text  # 24 and 48 s per hour


def test_the_cases_go_round_the_presets_then_the_durations():
    cases = plain_cases(13)
    assert [c[0] for c in cases[:4]] == ["nominal", "nominal", "paper", "noise_free"]
    assert [c[1] for c in cases] == list(range(SEED0, SEED0 + 13))
    assert [c[2] for c in cases[::4]] == [*DURATIONS_S, DURATIONS_S[0]]


@pytest.fixture(scope="module")
def flights():
    """A 600-s calibration box of the ``paper`` and the ``nominal`` preset."""
    overrides = {"trajectory.pattern": "calibration", "trajectory.duration_s": 600.0}
    return {
        p: simulate_flight(with_overrides(preset(p), overrides), 1) for p in ("paper", "nominal")
    }


def test_the_base_model_lacks_nothing_on_a_paper_flight(flights):
    """No external variation: the model's Earth field is the simulator's, to round-off
    (1e-9 nT on a field of 5e4 nT: the same IGRF grid along the same track)."""
    assert np.abs(unmodelled_external(flights["paper"])).max() < 1e-9


def test_the_base_model_lacks_the_external_field_across_the_main_field_only(flights):
    """On a nominal flight the ``diurnal`` channel records the external variation along the
    main field: what is left is across it. Along the true field's direction less than 1e-3 nT
    remains (that direction differs from IGRF's by |external| / |B| ~ 1e-5 rad); across it,
    most of the external variation's nT."""
    flight = flights["nominal"]
    extra = unmodelled_external(flight)
    t_b = flight.vector("truth_earth")
    along = np.sum(extra * t_b / np.linalg.norm(t_b, axis=1, keepdims=True), axis=1)
    assert np.abs(along).max() < 1e-3
    assert np.sqrt(np.mean(extra**2)) > 0.1
