"""The fault-injection suite of issue 20 (:mod:`tests.faults`) as tests.

Every generated case must pass the suite's checker: no traceback, internal error or hang; a
refusal is one ``aeromag … error:`` line on stderr; a faulted input is refused or accepted with
a warning that names the fault, never silently; no input changes; nothing is written before a
refusal; an accepted run writes its whole output set; no temporary file is left. A few cases run
again as a real process (what a user's terminal shows), and hypothesis corrupts the bytes of a
clean file and draws option values. Runs that do the work of ``kf``, ``discover`` or ``train``
(0.5 to 15 s each) and compensations of variants the default run tries in another form are
marked slow (``-m slow``); the rest, over 1200 cases, run by default (about 110 s on 2 cores).
"""

from __future__ import annotations

import shutil
import subprocess
import sys
import tempfile
from functools import partial
from pathlib import Path

import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from tests._helpers import examples
from tests.faults.cases import BAD, FORMATS, OK, Case, clean_bytes, setup
from tests.faults.suite import check, generate, run_case, table

CASES = generate()
CLASSES = {
    "file",
    "missing",
    "duplicated",
    "mistyped",
    "mis-unit",
    "NaN/inf",
    "paths",
    "option values",
    "hostile files",
    "clean",
}
COMMANDS = {
    "simulate",
    "info",
    "compensate",
    "reproduce-paper",
    "evaluate",
    "train",
    "discover",
    "demo",
    "convert",
    "bench",
}
#: Cases run again through the installed ``aeromag`` script: a refusal, a reader's error, an
#: option check, a path hazard, a hostile file and an accepted file with NaN samples.
IN_A_PROCESS = (
    "file/random_bytes/h5/info",
    "file/truncated_0.5/mat/tl",
    "option values/--r-std-nt='nan'/kf",
    "paths/input_named_report.json/lsq",
    "hostile files/config_random_bytes/simulate",
    "NaN/inf/ins_pitch_nan_burst/csv/lsq",
)
COMPENSATED = ("out/compensated.h5", "out/report.json", "out/compensation.png")


def _slow(case: Case) -> bool:
    """A run that gets past the checks to the work of kf, discover or train (0.5 to 15 s), or a
    compensation the default run tries in another form: a field fault in a CSV, XYZ or MAT file
    (tried in HDF5), a burst of ±inf (tried with NaN), an accepted file compensated with lsq
    (tried with tl)."""
    if case.expect != "refused" and (case.argv[0] in ("discover", "train") or "kf" in case.argv):
        return True
    if case.argv[0] != "compensate":
        return False
    if case.expect != "refused" and "lsq" in case.argv:
        return True
    in_text_or_mat = case.fault_class in ("missing", "duplicated", "mistyped") and not (
        case.argv[1].endswith(".h5")
    )
    return in_text_or_mat or "inf_burst/" in case.name or "neg_inf/" in case.name


def _run(case: Case) -> list[str]:
    """The checker's failures of ``case``, one line each with the command and what it printed."""
    with tempfile.TemporaryDirectory() as tmp:
        result = run_case(case, Path(tmp, "case"))
    said = (
        f"aeromag {' '.join(case.argv)} → exit {result.code} ({result.outcome}, expected "
        f"{case.expect}); stderr: {result.stderr.strip()[-400:]!r}"
    )
    if result.outcome == "skipped":
        return ["skipped"]
    return [f"{kind}: {detail} [{said}]" for kind, detail in result.failures]


def test_the_suite_covers_every_class_and_command_with_unique_ids() -> None:
    ids = [c.id for c in CASES]
    assert len(ids) == len(set(ids))
    assert {c.fault_class for c in CASES} == CLASSES
    assert {c.argv[0] for c in CASES} == COMMANDS
    assert sum(not _slow(c) for c in CASES) >= 500  # the minimum, in the default run
    assert all(
        c.expect in ("any", "refused") or set(c.expect.split("|")) <= {"refused", "warned", "clean"}
        for c in CASES
    )


@pytest.mark.parametrize(
    "case", [pytest.param(c, id=c.id, marks=[pytest.mark.slow] if _slow(c) else []) for c in CASES]
)
def test_bad_input_gets_a_clear_answer(case: Case) -> None:
    failures = _run(case)
    if failures == ["skipped"]:
        pytest.skip("no read-only folder here (root without chattr)")
    assert not failures, "\n".join(failures)


@pytest.mark.slow
@pytest.mark.parametrize("case_id", IN_A_PROCESS)
def test_a_real_process_exits_alike_without_a_traceback(case_id: str, tmp_path: Path) -> None:
    case = next(c for c in CASES if c.id == case_id)
    case.setup(tmp_path)
    argv = [a.replace("@/", f"{tmp_path}/") for a in case.argv]
    exe = Path(sys.executable).with_name("aeromag")
    run = subprocess.run(
        [str(exe), *argv], cwd=tmp_path, capture_output=True, text=True, timeout=300, check=False
    )
    assert "Traceback" not in run.stderr, run.stderr[-3000:]
    assert run.returncode in (0, 2), run.stderr[-3000:]
    assert run.returncode == run_case(case, tmp_path / "in-process").code


@settings(max_examples=examples(25, explore=60), deadline=None)  # 1-3 s an example
@given(
    fmt=st.sampled_from(FORMATS),
    where=st.floats(0.0, 1.0),
    data=st.binary(min_size=1, max_size=64),
    how=st.sampled_from(("replace", "insert", "cut")),
)
# a truth channel's value turned into ~1e300 nT: its RMSE overflowed to inf with a RuntimeWarning
@example(fmt="h5", where=0.96875, data=b"\x00\x00\x00\x00`", how="replace")
# two bytes of the root group's symbol-table entry (offset 1175 of the old-style groups that
# plain h5py writes): h5py's RuntimeError "unknown symbol table entry cache type" was an
# internal error
@example(fmt="h5", where=0.005, data=b"\x00\x03", how="replace")
def test_a_corrupted_file_is_read_or_refused(fmt: str, where: float, data: bytes, how: str) -> None:
    """Bytes of a clean file replaced, inserted or cut anywhere: ``tl`` reads the file (with a
    warning, or clean when the change is a plausible value) or refuses it in one line."""
    clean = clean_bytes(fmt)
    k = int(where * (len(clean) - 1))
    corrupt = {
        "replace": clean[:k] + data + clean[k + len(data) :],
        "insert": clean[:k] + data + clean[k:],
        "cut": clean[:k] + clean[k + len(data) :],
    }
    argv = ("compensate", f"@/in.{fmt}", "--method", "tl", "--out", "@/out")
    make = partial(setup, ops=(f"data:in.{fmt}",), make=lambda: corrupt[how])
    failures = _run(Case("hypothesis", "corrupt", argv, make, "any", COMPENSATED))
    assert not failures, "\n".join(failures)


@settings(max_examples=examples(25, explore=60), deadline=None)  # 1-3 s an example
@given(
    option=st.sampled_from(
        ("--tl-ridge", "--tl-trim", "--r-std-nt", "--segment", "--line", "--calibration-window")
    ),
    value=st.one_of(
        st.floats(allow_nan=True, allow_infinity=True),
        st.integers(-(10**30), 10**30),
        st.text(
            st.characters(blacklist_categories=("Cs",), blacklist_characters="\x00"), max_size=12
        ),
    ),
)
def test_any_option_value_runs_or_is_refused(option: str, value: float | int | str) -> None:
    """A drawn value for a numeric option of ``compensate``: it runs, or it is refused in one
    line; never an internal error, a non-finite number printed without a warning, or a hang."""
    text = repr(value) if isinstance(value, float) else str(value)
    extra = {
        "--calibration-window": ("--calibration-window", "10", text),
        "--segment": (f"--segment=0:{text}",),
    }.get(option, (f"{option}={text}",))
    method = "kf" if option == "--r-std-nt" else "tl"
    argv = ("compensate", "@/in.h5", "--method", method, "--out", "@/out", *extra)
    failures = _run(
        Case("hypothesis", "value", argv, partial(setup, ops=("in:in.h5",)), "any", COMPENSATED)
    )
    assert not failures, "\n".join(failures)


def test_the_table_counts_every_case_once(tmp_path: Path) -> None:
    """The README table of :func:`tests.faults.suite.table` on three cases of known outcome."""
    picked = [
        next(c for c in CASES if c.id == i)
        for i in ("missing/tt/h5/info", "NaN/inf/flux_a_y_nan_burst/h5/info", "clean/clean/h5/info")
    ]
    results = [run_case(c, tmp_path / str(k)) for k, c in enumerate(picked)]
    rows = {
        line.split(" | ")[0][2:]: line.split(" | ")[1:5] for line in table(results).splitlines()
    }
    assert rows["missing"] == ["1", "1", "0", "0"] and rows["NaN/inf"] == ["1", "0", "1", "0"]
    assert rows["clean"] == ["1", "0", "0", "1"] and rows["all"] == ["3", "1", "1", "1"]
    shutil.rmtree(tmp_path, ignore_errors=True)


def test_the_checker_finds_each_kind_of_failure(tmp_path: Path) -> None:
    """:func:`tests.faults.suite.check` on made-up runs: each failure is found, and only it."""
    old, new = ("file", 1, 1, "a"), ("file", 1, 2, "b")

    def kinds(code: int | str, expect: str = "refused", out: str = "", **kw: object) -> set[str]:
        err = str(kw.get("err", "aeromag compensate: error: bad input"))
        before, after = kw.get("before", {}), kw.get("after", {})
        case = Case("t", "t", ("compensate",), setup, expect, ("out/report.json",))
        return {k for k, _ in check(case, tmp_path, code, out, err, before, after).failures}

    assert kinds(2) == set()
    assert kinds(2, err="Traceback (most recent call last):\nValueError: x") == {"stderr not clean"}
    assert kinds(1, err="aeromag compensate: internal error: ValueError") == {"internal error"}
    assert kinds("ValueError: x") == {"traceback"}
    assert kinds("Hang: no answer") == {"hang"}
    assert kinds(2, before={"in.h5": old}, after={"in.h5": new}) == {"input modified"}
    assert kinds(2, after={"out/report.json": old}) == {"partial output set"}
    assert kinds(2, after={"out": ("dir",), "out/.aeromag-stage-1": ("dir",)}) == {
        "partial output set"
    }
    done = {"after": {"out/report.json": old}, "err": ""}
    assert kinds(0, OK, **done) == set()
    assert kinds(0, OK, err="") == {"partial output set"}  # the output set not written
    assert kinds(0, BAD, **done) == {"silent wrong result"}
    assert kinds(0, OK, "RMSE nan nT", **done) == {"silent wrong result"}
    warned = {**done, "err": "aeromag compensate: warning: flux_a: 3 spikes"}
    assert kinds(0, "refused", **warned) == {"accepted, should be refused"}
    assert kinds(0, BAD, **warned) == set()
    assert kinds(2, OK) == {"refused a usable input"}


@pytest.mark.slow
def test_the_script_prints_the_table_and_says_whether_all_passed() -> None:
    """``experiments/fault_suite.py`` run as a script, as its users run it."""
    script = Path(__file__).resolve().parents[1] / "experiments" / "fault_suite.py"
    run = subprocess.run(
        [sys.executable, str(script), "--only", "missing/tt/h5/"],
        capture_output=True,
        text=True,
        timeout=600,
        check=False,
    )
    assert run.returncode == 0, run.stderr[-3000:]  # refused by every reader: no failure
    printed = run.stdout
    assert "| missing | 5 | 5 | 0 | 0 | 0 | 0 | 0 | 0 | 0 | 0 |" in printed
    assert "5 cases in" in printed
