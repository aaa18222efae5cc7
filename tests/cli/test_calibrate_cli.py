"""From a calibration flight to a survey fleet to a live stream, through the command line:
``aeromag simulate --aircraft``, ``aeromag calibrate``, ``aeromag compensate --model`` (a file, a
fleet, on Ray) and ``aeromag stream`` reading standard input."""

from __future__ import annotations

import json
import os
import select
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from aeromag_env.cli.main import main
from aeromag_env.flight.files import read_flight

#: the aeromag command of this interpreter's environment
AEROMAG = [
    sys.executable,
    "-c",
    "import sys; from aeromag_env.cli.main import main; sys.exit(main(sys.argv[1:]))",
]
#: One aircraft: its box, a survey, and the survey after maintenance.
FLIGHTS = {
    "box": ["--pattern", "calibration", "--seed", "1"],
    "survey": ["--pattern", "survey", "--duration-s", "240", "--seed", "2"],
    "changed": [
        *("--pattern", "survey", "--duration-s", "240", "--seed", "2"),
        *("--permanent-shift-nt", "60", "-40", "30"),
    ],
}


@pytest.fixture(scope="module")
def fleet(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("aircraft")
    for name, args in FLIGHTS.items():
        out = folder / ("flights" if name != "box" else ".") / f"{name}.h5"
        assert main(["simulate", *args, "--aircraft", "7", "--out", str(out), "--quiet"]) == 0
    assert (
        main(["calibrate", str(folder / "box.h5"), "--method", "kf", "--out", str(folder / "cal")])
        == 0
    )
    return folder


def test_simulate_aircraft_keeps_the_coefficients_and_maintenance_shifts_them(fleet: Path):
    box, survey, changed = (
        read_flight(fleet / p) for p in ("box.h5", "flights/survey.h5", "flights/changed.h5")
    )
    coef = [
        np.asarray(json.loads(f.attrs["truth_coefficients"])["flux_a"]["permanent_nt"])
        for f in (box, survey, changed)
    ]
    np.testing.assert_array_equal(coef[0], coef[1])
    # 1e-9 nT: one addition of doubles, written and read as JSON text
    np.testing.assert_allclose(coef[2] - coef[1], [60.0, -40.0, 30.0], rtol=0, atol=1e-9)


def test_calibrate_then_compensate_with_the_model_warns_only_for_the_changed_aircraft(
    fleet: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
):
    model = str(fleet / "cal" / "model.json")
    capsys.readouterr()
    for name, warned in (("survey", False), ("changed", True)):
        args = ["compensate", str(fleet / "flights" / f"{name}.h5"), "--model", model]
        assert main([*args, "--out", str(tmp_path / name), "--no-html"]) == 0
        out, err = capsys.readouterr()
        assert out.startswith(f"kf: wrote {tmp_path / name}/compensated.h5")
        said = [line for line in err.splitlines() if "no longer fits" in line]
        assert bool(said) == warned, err
    assert said[0].startswith("aeromag compensate: warning: the calibrated kf model")
    assert "recalibrate" in said[0]


def test_compensate_needs_a_method_or_a_model(fleet: Path, capsys: pytest.CaptureFixture[str]):
    assert main(["compensate", str(fleet / "box.h5"), "--out", str(fleet / "x")]) == 2
    assert capsys.readouterr().err.startswith("aeromag compensate: error: --method is needed")


def test_a_fleet_with_a_model(fleet: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]):
    model = str(fleet / "cal" / "model.json")
    assert (
        main(["compensate", str(fleet / "flights"), "--model", model, "--out", str(tmp_path)]) == 0
    )
    out, err = capsys.readouterr()
    assert "0 of 2 flights failed" in out
    assert "changed.h5: warning: the calibrated kf model no longer fits" in err
    assert (tmp_path / "survey" / "compensated.h5").exists()


@pytest.mark.ray
def test_a_fleet_with_a_model_on_ray_equals_serial(local_ray: None, fleet: Path, tmp_path: Path):
    model = str(fleet / "cal" / "model.json")
    base = ["compensate", str(fleet / "flights"), "--model", model, "--no-html"]
    assert main([*base, "--out", str(tmp_path / "serial")]) == 0
    assert main([*base, "--out", str(tmp_path / "ray"), "--ray"]) == 0
    for name in ("survey", "changed"):
        a, b = (read_flight(tmp_path / r / name / "compensated.h5") for r in ("serial", "ray"))
        np.testing.assert_array_equal(a["aeromag_flux_a_c_x"], b["aeromag_flux_a_c_x"])


def _lines_within(proc: subprocess.Popen[str], count: int, timeout_s: float) -> str:
    """What the process wrote to stdout until ``count`` whole lines came, each within
    ``timeout_s`` [s] (a stream that does not flush per line never delivers them while its
    input stays open). Read from the pipe's descriptor: a buffered ``readline`` may take several
    lines into its buffer, where ``select`` no longer sees them."""
    assert proc.stdout is not None
    fd, got = proc.stdout.fileno(), b""
    while got.count(b"\n") < count:
        ready, _, _ = select.select([fd], [], [], timeout_s)
        assert ready, f"no line within {timeout_s} s; got {got!r}"
        chunk = os.read(fd, 1 << 16)
        assert chunk, f"the stream ended; got {got!r}"
        got += chunk
    return got.decode()


def test_stream_answers_each_line_as_it_comes_and_equals_compensate(fleet: Path, tmp_path: Path):
    """The CSV ``aeromag convert`` writes, fed line by line to ``aeromag stream`` (a bad line
    among them): each sample is answered while the input is still open, the bad line is one
    warning on stderr, and the values are ``compensate --model``'s."""
    model = fleet / "cal" / "model.json"
    csv_path = tmp_path / "survey.csv"
    assert main(["convert", str(fleet / "flights" / "survey.h5"), str(csv_path)]) == 0
    assert (
        main(
            [
                "compensate",
                str(csv_path),
                "--model",
                str(model),
                "--out",
                str(tmp_path / "o"),
                "--no-html",
            ]
        )
        == 0
    )
    text = csv_path.read_text().splitlines(keepends=True)
    head = next(i for i, line in enumerate(text) if not line.startswith("#"))
    lines = [*text[: head + 4], "1.0,oops\n", *text[head + 4 :]]
    proc = subprocess.Popen(
        [*AEROMAG, "stream", "--model", str(model)],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    assert proc.stdin is not None
    proc.stdin.writelines(lines[: head + 4])  # the header and three samples
    proc.stdin.flush()
    first = _lines_within(proc, 3, timeout_s=120.0)  # the header and two answers (kf: one back)
    out, err = proc.communicate("".join(lines[head + 4 :]), timeout=600)
    assert proc.returncode == 0, err
    rows = (first + out).splitlines(keepends=True)
    assert rows[0] == "tt,aeromag_flux_a_c_x,aeromag_flux_a_c_y,aeromag_flux_a_c_z\n"
    assert err.splitlines() == [
        f"aeromag stream: warning: line {head + 5}: 2 cells where the header has "
        f"{len(text[head].split(','))}; skipped"
    ]
    values = np.array([[float(c) for c in r.split(",")] for r in rows[1:]])
    ref = read_flight(tmp_path / "o" / "compensated.h5")
    whole = np.column_stack([ref[f"aeromag_flux_a_c_{a}"] for a in "xyz"])
    kept = np.all(np.isfinite(whole), axis=1)
    np.testing.assert_array_equal(values[:, 0], ref.tt[kept])
    np.testing.assert_allclose(values[:, 1:], whole[kept], rtol=0, atol=1e-9)  # 1e-9 nT: the claim


def test_stream_refuses_a_bad_model_or_date_before_reading(
    fleet: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
):
    model = str(fleet / "cal" / "model.json")
    assert main(["stream", "--model", model, "--date", "1800-01-01"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("aeromag stream: error: the stream's date")
    (tmp_path / "bad.json").write_text("{}")
    assert main(["stream", "--model", str(tmp_path / "bad.json")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "not an aeromag compensation model" in err
