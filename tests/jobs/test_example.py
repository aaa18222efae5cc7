"""``aeromag example``: the sample survey file of the guides, one command away."""

from __future__ import annotations

import numpy as np
import pytest

from aeromag_env.flight.files import read_flight
from aeromag_env.flight.validation import FlightFileWarning
from aeromag_env.jobs.example import SEED, contractor_flight
from tests._helpers import experiment, run_cli


def test_the_sample_is_the_walkthrough_scripts_file_bit_for_bit() -> None:
    """The guide's figures are the experiment's file's: the two must stay one flight."""
    ours, theirs = contractor_flight(), experiment("own_flight_file")["raw_flight"](SEED)
    assert ours.names == theirs.names
    for name in ours.names:
        np.testing.assert_array_equal(ours[name], theirs[name], err_msg=name)


def test_the_command_writes_a_file_every_tool_reads_with_its_faults(tmp_path, capsys) -> None:
    path = tmp_path / "survey_raw.xyz"
    assert run_cli(["example", str(path)]) == 0
    assert capsys.readouterr().out.startswith(f"wrote {path}: 20585 samples")
    with pytest.warns(FlightFileWarning, match=r"mag_1_uc: 1 spike\(s\) \(t = 1700 s"):
        flight = read_flight(path)  # the Geosoft names read as ours, the spike warned of
    assert {"flux_a_x", "mag_1_uc", "mag_1_c", "ins_pitch", "utm_z"} <= set(flight.names)
    assert int(np.isnan(flight["ins_pitch"]).sum()) == 3
    assert float(np.max(np.diff(flight.tt))) > 30.0  # the logger gap [s]
