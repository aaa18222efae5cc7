"""Calibrate, then compensate with the model, on MagNav.jl's real Tolles–Lawson segment.

``python experiments/magnav_tl_check.py PATH [--out DIR]`` reads MagNav.jl's
``test/test_data/test_data_TL.mat`` (a ``TL_data`` struct: ``fs`` [Hz], ``flux_a_x/y/z`` and
``mag_1_uc`` [nT], 1 000 samples of a real flight, and MagNav's own results: ``TL_a_1``, its 18
coefficients, and ``mag_1_c``, its compensated field), writes the flight as a file (time
``k / fs``) and runs the commands' jobs on it:

* ``aeromag calibrate FILE --method tl`` then ``aeromag compensate FILE --model model.json``,
  against ``aeromag compensate FILE --method tl``: the largest difference of the compensated
  field [nT] (the claim: within 1e-9 nT) and whether the flagged samples agree;
* against MagNav.jl's own numbers, with its test's settings (``test_data_params.mat``: band-pass
  0.1–0.9 Hz, trim 20, λ = 0.001, :data:`MAGNAV_RIDGE`): the coefficients' largest relative
  difference from ``TL_a_1`` (the fit's condition number is in the thousands on 100 s of data:
  coefficients differ where the compensated field does not) and the standard deviation of the
  compensated field's difference from ``mag_1_c`` [nT] (a constant apart: the mean correction is
  removed here; MagNav.jl's own test asks < 0.1 nT of its Julia implementation).

Writes ``magnav_tl_check.json`` (numbers only: no data; the input's SHA-256, the command, the
date and the package version) in ``--out`` (default ``results/magnav_tl_check``). The copy
beside this script is the run on the real file; the data stays out of the repository (the tests
run this script on a synthetic file in the same layout).
"""

from __future__ import annotations

import argparse
import datetime as _dt
import hashlib
import json
import sys
import tempfile
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import scipy.io

if __package__ in (None, ""):  # run by its path, from anywhere: this checkout's packages first
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import aeromag_env
from aeromag_env.atomic import write_text
from aeromag_env.flight.data import Flight
from aeromag_env.flight.files import write_flight
from aeromag_env.jobs.calibrate import calibrate
from aeromag_env.jobs.compensate import compensate

#: The struct's fields the flight file gets.
CHANNELS = ("flux_a_x", "flux_a_y", "flux_a_z", "mag_1_uc")
#: The compensated channel both runs write.
OUTPUT = "aeromag_mag_1_c"
#: The ridge parameter λ of MagNav.jl's Tolles–Lawson test (its test_data_params.mat TL.lambda);
#: the band-pass (0.1–0.9 Hz) and trim (20) there are this package's defaults.
MAGNAV_RIDGE = 0.001


def read_segment(path: Path) -> tuple[Flight, dict[str, np.ndarray]]:
    """The segment as a flight (time ``k / fs`` [s]) and MagNav's results (``TL_a_1``,
    ``mag_1_c``) where the file has them."""
    struct = scipy.io.loadmat(path, squeeze_me=True)["TL_data"]
    data = {name: np.asarray(struct[name].item(), dtype=float) for name in struct.dtype.names}
    fs = float(data["fs"])
    n = data["mag_1_uc"].size
    fields = {"tt": np.arange(n) / fs, **{c: data[c].ravel() for c in CHANNELS}}
    theirs = {k: data[k].ravel() for k in ("TL_a_1", "mag_1_c") if k in data}
    return Flight(fields, {}), theirs


def check(path: Path, work: Path) -> dict[str, Any]:
    """The figures of the module docstring, computed in the folder ``work``."""
    flight, theirs = read_segment(path)
    file = write_flight(flight, work / "segment.h5")
    cal = calibrate(file, "tl", out=work / "cal", html=False, tl_ridge=MAGNAV_RIDGE)
    applied = compensate(file, out=work / "applied", model=work / "cal" / "model.json", html=False)
    direct = compensate(file, "tl", out=work / "direct", html=False, tl_ridge=MAGNAV_RIDGE)
    a, b = applied.flight[OUTPUT], direct.flight[OUTPUT]
    both = np.isfinite(a) & np.isfinite(b)
    out: dict[str, Any] = {
        "samples": int(flight.n),
        "sample_rate_hz": float(flight.sample_rate_hz),
        "compared_samples": int(both.sum()),
        "same_flagged_samples": bool(np.array_equal(np.isnan(a), np.isnan(b))),
        "model_minus_direct_max_abs_nt": float(np.max(np.abs(a[both] - b[both]))),
        "equal_within_1e-9_nt": bool(np.max(np.abs(a[both] - b[both])) <= 1e-9),
        "warnings": {"applied": len(applied.warnings), "direct": len(direct.warnings)},
    }
    coef = cal.model.tl_coefficients()
    if "TL_a_1" in theirs:
        rel = np.abs(coef - theirs["TL_a_1"]) / np.abs(theirs["TL_a_1"])
        out["coefficients_max_relative_difference_to_magnav"] = float(rel.max())
    if "mag_1_c" in theirs:
        out["compensated_difference_std_to_magnav_nt"] = float(np.nanstd(b - theirs["mag_1_c"]))
    return out


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("path", type=Path, help="MagNav.jl's test/test_data/test_data_TL.mat")
    parser.add_argument("--out", type=Path, default=Path("results/magnav_tl_check"))
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as work:
        figures = check(args.path, Path(work))
    result = {
        "command": "python experiments/magnav_tl_check.py "
        + " ".join(sys.argv[1:] if argv is None else argv),
        "date": _dt.date.today().isoformat(),
        "package_version": aeromag_env.__version__,
        "input": args.path.name,
        "input_sha256": hashlib.sha256(args.path.read_bytes()).hexdigest(),
        **figures,
    }
    args.out.mkdir(parents=True, exist_ok=True)
    write_text(args.out / "magnav_tl_check.json", json.dumps(result, indent=1) + "\n")
    print(json.dumps(result, indent=1))
    return 0 if figures["equal_within_1e-9_nt"] and figures["same_flagged_samples"] else 1


if __name__ == "__main__":
    sys.exit(main())
