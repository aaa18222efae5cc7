"""``aeromag example``: the sample survey file of the guides, one command away."""

from __future__ import annotations

import numpy as np
import pytest

from aeromag_env.flight.files import read_flight
from aeromag_env.flight.validation import FlightFileWarning
from aeromag_env.jobs.example import SEED, contractor_flight
from aeromag_env.simulation.config import preset, with_overrides
from aeromag_env.simulation.simulate import simulate_flight
from tests._helpers import run_cli


def test_the_sample_is_the_simulated_flight_as_a_contractor_delivers_it() -> None:
    """Against the simulator's own flight: the fluxgate read in sensor axes (right, down,
    forward), the vendor's channel the scalar less the true interference within its noise, the
    spike one sample of 1e6 nT."""
    ours = contractor_flight()
    cfg = with_overrides(preset("nominal"), {"trajectory.pattern": "calibration+survey"})
    sim = simulate_flight(cfg, rng=SEED)
    kept = np.isin(sim.tt, ours["TIME"])
    assert int(kept.sum()) == ours.n and ours.n < sim.n  # the samples of the gap are gone
    body = sim.vector("flux_a")[kept]
    sensor = np.column_stack([ours[f"FLUXA_{a}"] for a in "XYZ"])
    np.testing.assert_array_equal(sensor, body[:, [1, 2, 0]])  # x, y, z = right, down, forward
    vendor = ours["COMPMAG1"] - (sim["mag_1_uc"] - sim["truth_interf_mag_1"])[kept]
    assert abs(float(np.std(vendor)) - 0.05) < 0.005  # [nT]: the vendor's noise, 20 000 samples
    jump = ours["UNCOMPMAG1"] - sim["mag_1_uc"][kept]
    assert np.count_nonzero(jump) == 1 and abs(float(jump.max()) - 1e6) < 1e-6  # [nT]: rounding


def test_the_command_writes_a_file_every_tool_reads_with_its_faults(tmp_path, capsys) -> None:
    path = tmp_path / "survey_raw.xyz"
    assert run_cli(["example", str(path)]) == 0
    assert capsys.readouterr().out.startswith(f"wrote {path}: 20585 samples")
    with pytest.warns(FlightFileWarning, match=r"mag_1_uc: 1 spike\(s\) \(t = 1700 s"):
        flight = read_flight(path)  # the Geosoft names read as ours, the spike warned of
    assert {"flux_a_x", "mag_1_uc", "mag_1_c", "ins_pitch", "utm_z"} <= set(flight.names)
    assert int(np.isnan(flight["ins_pitch"]).sum()) == 3
    assert float(np.max(np.diff(flight.tt))) > 30.0  # the logger gap [s]
