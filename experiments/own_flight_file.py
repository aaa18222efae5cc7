"""The README's "Your own flight files" walkthrough, from a raw Geosoft XYZ file to a report.

No real survey file may be shipped (the public SGL flights are under an acceptable-use agreement),
so this script writes one the way a contractor delivers it (the file of ``aeromag example``,
:mod:`aeromag_env.jobs.example`): a simulated calibration box and
survey lines (nominal preset, seed 11) with Geosoft column names (``UNCOMPMAG1``, ``FLUXA_X``,
``ROLL``, ``AZIMUTH``…), ``*`` for missing values, no simulator truth and no attributes, and with
what real files bring: the fluxgate mounted as an axis swap (sensor x, y, z = body right, down,
forward, as SGL's ``flux_a``), a 30 s logger gap on a survey line, one 1e6 nT spike in the
scalar, a few samples of missing attitude, and the vendor's compensated channel ``COMPMAG1``
(here the scalar minus the true interference plus 0.05 nT of noise). It then runs
``aeromag info`` and ``aeromag compensate`` (``tl`` fitted on the calibration line, and ``kf``)
and prints what they print, stderr included.

Usage::

    python experiments/own_flight_file.py [--out results/own_flight_file]
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import sys
from pathlib import Path

if __package__ in (None, ""):  # run by its path, from anywhere: this checkout's packages first
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from aeromag_env.cli.main import main as aeromag
from aeromag_env.jobs.example import example


def run(argv: list[str]) -> tuple[int, str]:
    """``aeromag ARGV``: exit code and what it printed (stdout, then stderr)."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = aeromag(argv)
    return code, out.getvalue() + err.getvalue()


def walkthrough(out: Path) -> dict[str, object]:
    """Write the raw file, run the commands, return their outputs and the key figures."""
    out.mkdir(parents=True, exist_ok=True)
    raw = example(out / "survey_raw.xyz").path  # the file of aeromag example
    steps = {
        "info": ["info", str(raw)],
        "tl": [
            "compensate",
            str(raw),
            "--method",
            "tl",
            "--calibration-line",
            "--out",
            str(out / "tl"),
        ],
        "kf": ["compensate", str(raw), "--method", "kf", "--out", str(out / "kf")],
    }
    printed = {}
    for name, argv in steps.items():
        code, text = run(argv)
        printed[name] = {"argv": argv, "exit": code, "printed": text.replace(str(out), "OUT")}
    figures = {name: json.loads((out / name / "report.json").read_text()) for name in ("tl", "kf")}
    return {"printed": printed, "reports": figures}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="results/own_flight_file", help="output folder")
    args = parser.parse_args(argv)
    result = walkthrough(Path(args.out))
    for step in result["printed"].values():  # type: ignore[attr-defined]
        print(f"$ aeromag {' '.join(step['argv'])}  # exit {step['exit']}")
        print(step["printed"])
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
