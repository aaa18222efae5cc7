"""Warnings on stderr as docs/howto/bad-input.md says: every doubt about a single file's input is
one line ``aeromag CMD: warning: …`` on stderr, as well as an entry of ``report.json``."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from aeromag_env.flight.data import Flight
from aeromag_env.flight.files import write_flight
from tests._flights import simulated
from tests._helpers import run_cli

#: Where the spike goes (sample 3000, t = 300 s of a 10 Hz flight) and how large it is [nT]: a
#: logger's wild sample, far beyond the 12 robust σ of the spike test.
SPIKE_AT, SPIKE_NT = 3000, 1e6


def spiked_file(folder: Path) -> Path:
    """A 10-minute simulated calibration flight with one scalar spike, as CSV."""
    flight = simulated(trajectory__duration_s=600.0)
    fields = dict(flight.fields)
    scalar = np.array(fields["mag_1_uc"], dtype=float)
    scalar[SPIKE_AT] += SPIKE_NT
    fields["mag_1_uc"] = scalar
    path = folder / "spiked.csv"
    write_flight(Flight(fields, dict(flight.attrs)), path)
    return path


@pytest.mark.parametrize("command", ["compensate", "calibrate"])
def test_a_single_file_command_prints_each_input_warning_on_stderr(
    command: str, tmp_path: Path, capsys
) -> None:
    out = tmp_path / "tl"
    argv = [command, str(spiked_file(tmp_path)), "--method", "tl", "--out", str(out)]
    assert run_cli(argv) == 0
    stderr = capsys.readouterr().err.splitlines()
    problems = json.loads((out / "report.json").read_text())["input_problems"]
    spikes = [p for p in problems if p.startswith("mag_1_uc: 1 spike(s)")]
    assert len(spikes) == 1, problems  # the spike is an input problem of the report
    warned = [line.removeprefix(f"aeromag {command}: warning: ") for line in stderr]
    for problem in problems:  # each one line on stderr, once
        assert warned.count(problem) == 1, (problem, stderr)
    assert "t = 300 s" in spikes[0]
