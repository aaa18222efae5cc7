"""Discovery on flights over magnetic ground: the verdict says what it cannot judge."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import pytest

from aeromag_env.cli.main import main
from aeromag_env.discovery.report import SLOW_RESIDUAL_NT
from aeromag_env.discovery.suite import base_config
from aeromag_env.discovery.workflow import discover
from aeromag_env.flight.files import write_flight
from aeromag_env.simulation.config import GeologyConfig
from aeromag_env.simulation.simulate import simulate_flight


@pytest.mark.slow
def test_a_slow_residual_the_candidates_leave_is_a_caveat_on_stderr_and_in_the_report(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """30 nT of ground under the lines: the noise model's slow part far above the threshold,
    one warning line naming the slow effects that cannot be judged; the same flight without
    ground has none."""
    cfg = base_config(1500.0)
    flat = discover(simulate_flight(cfg, 91_010)).report
    assert flat["caveats"] == []
    ground = simulate_flight(dataclasses.replace(cfg, geology=GeologyConfig(rms_nt=30.0)), 91_010)
    path = write_flight(ground, tmp_path / "ground.h5")
    assert main(["discover", str(path), "--out", str(tmp_path / "d")]) == 0
    err = [ln for ln in capsys.readouterr().err.splitlines() if "slow signal" in ln]
    assert len(err) == 1 and err[0].startswith("aeromag discover: warning: the residual holds")
    assert "external_field_variation" in err[0] and "geology" in err[0]
    report = json.loads((tmp_path / "d" / "report.json").read_text())
    assert report["caveats"] and report["caveats"][0] in err[0]
    assert max(report["diagnostics"]["noise_model_after"]["fogm_std_nt"]) > 2 * SLOW_RESIDUAL_NT
    assert "**Caveat:**" in (tmp_path / "d" / "report.md").read_text()
