import hashlib
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from aeromag_env.cli.main import main
from aeromag_env.flight.files import read_flight


def _sha(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


@pytest.mark.parametrize("suffix", [".h5", ".csv"])
def test_simulate_writes_readable_flight(tmp_path, capsys, suffix):
    out = tmp_path / f"flight{suffix}"
    args = ["simulate", "--pattern", "calibration", "--preset", "nominal", "--seed", "3"]
    assert main([*args, "--out", str(out), "--quiet"]) == 0
    line = capsys.readouterr().out.strip()
    assert line.startswith(f"wrote {out}") and "12 maneuver windows" in line and "\n" not in line
    f = read_flight(out, needs=("tt", "position", "attitude", "date", "flux_a", "mag_1_uc"))
    assert len(f.maneuver_windows()) == 12
    assert json.loads(f.attrs["config"])["preset"] == "nominal"


def test_same_seed_identical_file_different_seed_different(tmp_path):
    paths = [tmp_path / n for n in ("a.csv", "b.csv", "c.csv")]
    for p, seed in zip(paths, ("1", "1", "2"), strict=True):
        base = ["simulate", "--seed", seed, "--duration-s", "120", "--quiet"]
        assert main([*base, "--out", str(p)]) == 0
    assert _sha(paths[0]) == _sha(paths[1])
    assert _sha(paths[0]) != _sha(paths[2])
    h5 = [tmp_path / "a.h5", tmp_path / "b.h5"]
    for p in h5:
        assert (
            main(["simulate", "--seed", "1", "--duration-s", "120", "--quiet", "--out", str(p)])
            == 0
        )
    a, b = read_flight(h5[0]), read_flight(h5[1])
    assert a.attrs == b.attrs and all(np.array_equal(a[n], b[n]) for n in a.names)


def test_duration_and_config_file(tmp_path):
    cfg = tmp_path / "cfg.json"
    cfg.write_text(json.dumps({"preset": "custom", "fluxgate_noise": {"white_std_nt": 3.0}}))
    out = tmp_path / "f.h5"
    assert (
        main(
            [
                "simulate",
                "--config",
                str(cfg),
                "--pattern",
                "survey",
                "--duration-s",
                "60",
                "--out",
                str(out),
                "--quiet",
            ]
        )
        == 0
    )
    f = read_flight(out)
    assert f.n == 600
    assert json.loads(f.attrs["config"])["fluxgate_noise"]["white_std_nt"] == 3.0


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["simulate", "--out", "x.txt"], "--out must end in .h5, .hdf5, .csv"),
        (["simulate", "--out", "x.h5", "--preset", "bogus"], "invalid choice: 'bogus'"),
        (["simulate", "--out", "x.h5", "--pattern", "spiral"], "invalid choice: 'spiral'"),
        (["simulate", "--out", "x.h5", "--duration-s", "-3"], "--duration-s must be > 0"),
        (["simulate", "--out", "x.h5", "--seed", "-1"], "--seed must be ≥ 0"),
        (["simulate", "--out", "x.h5", "--config", "missing.json"], "cannot read configuration"),
    ],
)
def test_bad_arguments_one_line_error(tmp_path, capsys, monkeypatch, argv, message):
    monkeypatch.chdir(tmp_path)
    try:
        code = main(argv)
    except SystemExit as e:  # argparse errors exit through SystemExit
        code = e.code
    err = capsys.readouterr().err
    assert code == 2
    assert message in err and err.count("\n") == 1 and "Traceback" not in err
    assert not (tmp_path / "x.h5").exists()


def test_output_equal_to_config_input_refused(tmp_path, capsys):
    cfg = tmp_path / "cfg.h5"  # a config file that happens to have a flight-file suffix
    cfg.write_text("{}")
    before = _sha(cfg)
    assert main(["simulate", "--config", str(cfg), "--out", str(cfg), "--quiet"]) == 2
    assert "is the input" in capsys.readouterr().err
    assert _sha(cfg) == before


@pytest.mark.slow
def test_info_and_demo_through_the_console_script(tmp_path):
    exe = Path(sys.executable).with_name("aeromag")
    demo = subprocess.run(
        [str(exe), "demo", "--out", str(tmp_path / "demo")],
        capture_output=True,
        text=True,
        check=False,
    )
    assert demo.returncode == 0, demo.stderr
    assert (tmp_path / "demo" / "flight.png").stat().st_size > 10_000
    summary = (tmp_path / "demo" / "summary.md").read_text()
    assert all(f"| {m} |" in summary for m in ("kf", "fakf", "lsq", "tl"))
    assert "summary.md" in demo.stdout
    info = subprocess.run(
        [str(exe), "info", str(tmp_path / "demo" / "flight.h5"), "--json"],
        capture_output=True,
        text=True,
        check=False,
    )
    assert info.returncode == 0, info.stderr
    assert "maneuver" in info.stdout
    bad = tmp_path / "bad.h5"
    bad.write_bytes(b"not an hdf5 file")
    res = subprocess.run([str(exe), "info", str(bad)], capture_output=True, text=True, check=False)
    assert res.returncode != 0


def test_help_for_every_subcommand(capsys):
    for cmd in ("simulate", "info", "demo", "bench"):
        with pytest.raises(SystemExit) as e:
            main([cmd, "--help"])
        assert e.value.code == 0
    assert "--duration-s" in capsys.readouterr().out
