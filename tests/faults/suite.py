"""The fault-injection suite of issue 20: bad input of every class through every command.

:func:`generate` gathers the cases, class by class, from :mod:`tests.faults.cases` (the commands;
a small clean simulated flight whose files are written there, not by the package's writers;
broken files; missing, duplicated, mistyped and mis-unit fields; NaN/inf bursts and spikes) and
:mod:`tests.faults.hazards` (path hazards; extreme and malformed option values; hostile
hyperparameter, policy, mount and configuration files; clean runs). :func:`run_case` runs one
case in-process (``aeromag_env.cli.main.main``) in a folder of its own and :func:`check` lists
its failures (:data:`FAILURES`). ``demo``, ``reproduce-paper``, ``bench`` and ``train`` get
hazards that must be refused before the work starts: their work is replaced by a sentinel that
fails the case when reached. :func:`table` and :func:`failure_groups` report a run; the script
``experiments/fault_suite.py`` runs the whole suite and prints them.
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import json
import os
import re
import shutil
import signal
import subprocess
import warnings
from collections import Counter, defaultdict
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from unittest import mock

from tests.faults.cases import (
    Case,
    field_cases,
    file_cases,
    nonfinite_cases,
    unit_cases,
)
from tests.faults.hazards import (
    WORK,
    clean_cases,
    hostile_cases,
    path_cases,
    value_cases,
)

OUTCOMES = ("refused", "warned", "clean")
#: Failure kinds; the first five have their own columns in the table.
FAILURES = (
    "traceback",
    "internal error",
    "silent wrong result",
    "input modified",
    "partial output set",
    "hang",
    "accepted, should be refused",
    "refused a usable input",
    "stderr not clean",
    "work started before refusing",
)
TIME_LIMIT_S = 120.0

# ---------------------------------------------------------------------------------------------
# All the cases


def generate() -> list[Case]:
    """Every case, class by class."""
    classes = (
        file_cases,
        field_cases,
        unit_cases,
        nonfinite_cases,
        path_cases,
        value_cases,
        hostile_cases,
        clean_cases,
    )
    return [case for make in classes for case in make()]


# ---------------------------------------------------------------------------------------------
# Running and checking


class WorkStarted(BaseException):
    """The sentinel standing for a heavy command's work was reached (a BaseException, so that
    the command line's handler of internal errors lets it through)."""


class Hang(BaseException):
    """A case ran past its time limit."""


@dataclass
class Result:
    """What a case did: its exit status (or the exception that escaped), outcome (refused,
    warned, clean or failed) and failures (kind, detail)."""

    case: Case
    code: int | str
    outcome: str
    failures: list[tuple[str, str]]
    stdout: str
    stderr: str


def snapshot(root: Path) -> dict[str, tuple]:
    """Every entry under ``root`` by relative path: links (target, the target's hash), folders,
    files (size, mtime, hash)."""
    found: dict[str, tuple] = {}
    for top, dirs, files in os.walk(root):
        for p in (Path(top, n) for n in dirs + files):
            digest = hashlib.sha256(p.read_bytes()).hexdigest() if p.is_file() else None
            st = p.lstat()
            if p.is_symlink():
                found[str(p.relative_to(root))] = ("link", os.readlink(p), digest)
            else:
                kind = ("dir",) if p.is_dir() else ("file", st.st_size, st.st_mtime_ns, digest)
                found[str(p.relative_to(root))] = kind
    return found


def _freeze(folder: Path, names: tuple[str, ...], on: bool) -> bool:
    """Make folders read-only, or writable again: ``chattr ±i`` as root (whom permissions do not
    stop), else the permission bits. Whether every folder now refuses a new file."""
    for path in (folder / n for n in names):
        chattr = ["chattr", "+i" if on else "-i", str(path)]
        root = os.geteuid() == 0 and shutil.which("chattr") is not None
        if not (root and subprocess.run(chattr, capture_output=True, check=False).returncode == 0):
            path.chmod(0o555 if on else 0o755)
    return all(_refuses_files(folder / n) for n in names)


def _refuses_files(path: Path) -> bool:
    try:
        (path / ".probe").touch()
    except OSError:
        return True
    (path / ".probe").unlink()
    return False


@contextlib.contextmanager
def _time_limit(seconds: float) -> Iterator[None]:
    """Raise :class:`Hang` after ``seconds`` (in the main thread; elsewhere no limit)."""

    def fire(*_: object) -> None:
        raise Hang(f"no answer in {seconds:g} s")

    try:
        previous = signal.signal(signal.SIGALRM, fire)
    except ValueError:  # not the main thread
        yield
        return
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


def _invoke(case: Case, argv: list[str], folder: Path) -> tuple[int | str, str, str]:
    """``aeromag ARGV`` in-process in ``folder``: the exit status (or the exception that escaped,
    as text), stdout, and stderr with the Python warnings a terminal would show."""
    from aeromag_env.cli.main import main

    out, err, here = io.StringIO(), io.StringIO(), os.getcwd()
    heavy = argv[0] in WORK and case.expect == "refused"
    sentinel = mock.patch(WORK[argv[0]], side_effect=WorkStarted(argv[0])) if heavy else None
    with contextlib.ExitStack() as stack:
        stack.enter_context(contextlib.redirect_stdout(out))
        stack.enter_context(contextlib.redirect_stderr(err))
        caught = stack.enter_context(warnings.catch_warnings(record=True))
        warnings.simplefilter("always")
        stack.enter_context(sentinel or contextlib.nullcontext())
        stack.enter_context(_time_limit(TIME_LIMIT_S))
        os.chdir(folder)
        try:
            code: int | str = main(argv)
        except SystemExit as e:  # argparse
            code = e.code if isinstance(e.code, int) else 0 if e.code is None else 2
        except (Exception, Hang, WorkStarted) as e:  # a real run would end in a traceback
            code = f"{type(e).__name__}: {e}"
        finally:
            os.chdir(here)
    shown = "".join(f"{w.category.__name__}: {w.message}\n" for w in caught)
    return code, out.getvalue(), err.getvalue() + shown


def run_case(case: Case, folder: Path) -> Result:
    """Set ``case`` up in ``folder`` (created), run it in-process and check it (outcome
    ``skipped`` when its read-only folders cannot be made read-only here)."""
    folder.mkdir(parents=True, exist_ok=True)
    case.setup(folder)
    argv = [a.replace("@/", f"{folder}/") for a in case.argv]
    if not _freeze(folder, case.frozen, True):  # root without chattr: no read-only folder here
        _freeze(folder, case.frozen, False)
        return Result(case, "skipped", "skipped", [], "", "")
    try:
        before = snapshot(folder)
        code, out, err = _invoke(case, argv, folder)
        after = snapshot(folder)
    finally:
        _freeze(folder, case.frozen, False)
    return check(case, folder, code, out, err, before, after)


_WARNING = re.compile(r"aeromag( [\w-]+)?: warning: ")
_ERROR = re.compile(r"aeromag( [\w-]+)?: error: ")


def check(
    case: Case, folder: Path, code: int | str, out: str, err: str, before: dict, after: dict
) -> Result:
    """The failures of one run (:data:`FAILURES`) from its exit status, output and files."""
    fails: list[tuple[str, str]] = []
    if isinstance(code, str):
        kind = {"WorkStarted": FAILURES[-1], "Hang": "hang"}.get(code.split(":")[0], "traceback")
        fails.append((kind, code[:300]))
    elif code not in (0, 2):
        fails.append(("internal error", f"exit status {code}: {_last(err)}"))
    outcome = "failed" if fails else "refused" if code == 2 else "clean"
    if outcome == "clean" and _warned(case, folder, out, err):
        outcome = "warned"
    allowed = OUTCOMES if case.expect == "any" else case.expect.split("|")
    if outcome in OUTCOMES and outcome not in allowed:
        kind = {
            "clean": "silent wrong result",
            "warned": "accepted, should be refused",
            "refused": "refused a usable input",
        }[outcome]
        fails.append((kind, f"expected {case.expect}: {_last(err) or _last(out)}"))
    if outcome == "clean" and re.search(r"\b(nan|inf)\b", out, re.IGNORECASE):
        fails.append(("silent wrong result", f"non-finite number printed: {_last(out, 'nan')}"))
    notes = [ln for ln in err.splitlines() if ln.strip() and not _WARNING.match(ln)]
    one_line = len(notes) == 1 and _ERROR.match(notes[0])
    if (code == 2 and not one_line) or (code == 0 and notes):
        fails.append(("stderr not clean", " ⏎ ".join(notes)[:300] or "(nothing on stderr)"))
    fails += _file_failures(case, before, after, code == 0)
    return Result(case, code, outcome, fails, out, err)


def _last(text: str, containing: str = "") -> str:
    """The last non-empty line of ``text`` (holding ``containing``, in lower case)."""
    lines = [ln for ln in text.splitlines() if ln.strip() and containing in ln.lower()]
    return lines[-1][:200] if lines else ""


def _warned(case: Case, folder: Path, out: str, err: str) -> bool:
    """A warning that names the fault (:attr:`Case.about`): an ``aeromag … warning:`` line on
    stderr, a problem listed by ``info``, or in report.json ``input_problems``, ``warnings`` or
    the flagged samples."""
    said = [ln for ln in err.splitlines() if _WARNING.match(ln)]
    if case.argv[0] == "info":
        said += out.partition("\nproblems: ")[2].splitlines()[1:]
    for path in (folder / o for o in case.outputs if o.endswith("report.json")):
        report = json.loads(path.read_text(encoding="utf-8")) if path.is_file() else {}
        said += [str(p) for p in [*report.get("input_problems", []), *report.get("warnings", [])]]
        flagged = report.get("flagged_samples") or report.get("metrics", {}).get("flagged_samples")
        if flagged and (flagged.get("count") or flagged.get("spikes")):
            said.append(json.dumps(flagged))
    return any(re.search(case.about, line) for line in said)


def _file_failures(case: Case, before: dict, after: dict, ok: bool) -> list[tuple[str, str]]:
    """An input changed; on refusal a file written; on success an output missing or not
    rewritten; a temporary file left."""
    outputs, fails = set(case.outputs), []
    changed = [p for p, e in before.items() if e != ("dir",) and after.get(p) != e]
    changed = [p for p in changed if not (ok and p in outputs)]
    if changed:
        kind = "partial output set" if changed[0] in outputs else "input modified"
        fails.append((kind, f"{changed[0]} changed or removed"))
    new = [p for p in after if p not in before]
    temps = [p for p in new if re.match(r"\..*(tmp|aeromag)", Path(p).name)]
    written = [p for p in new if after[p][0] != "dir" and p not in temps]
    old = [o for o in case.outputs if after.get(o, ("",))[0] != "file" or after[o] == before.get(o)]
    if temps:
        fails.append(("partial output set", f"temporary left: {temps[0]}"))
    if not ok and written:
        fails.append(("partial output set", f"written before refusing: {', '.join(written[:3])}"))
    if ok and old:
        fails.append(("partial output set", f"missing or not rewritten: {', '.join(old)}"))
    return fails


# ---------------------------------------------------------------------------------------------
# Report


def table(results: list[Result]) -> str:
    """The README table "What bad input gets": per class, the cases, their outcomes (of those
    without a failure) and the cases with each failure."""
    main, counted = FAILURES[:5], ("refused, one-line error", "accepted with a warning", "clean")
    rows = [
        "| fault class | cases | " + " | ".join((*counted, *main)) + " | other failures |",
        "|---|" + "---:|" * (len(counted) + len(main) + 2),
    ]
    for cls in [*dict.fromkeys(r.case.fault_class for r in results), "all"]:
        rs = [r for r in results if cls in ("all", r.case.fault_class)]
        kinds = [{k for k, _ in r.failures} for r in rs]
        good = Counter(r.outcome for r, k in zip(rs, kinds, strict=True) if not k)
        cells = [len(rs), *(good[o] for o in OUTCOMES), *(sum(m in k for k in kinds) for m in main)]
        cells.append(sum(bool(k - set(main)) for k in kinds))
        rows.append(f"| {cls} | " + " | ".join(map(str, cells)) + " |")
    return "\n".join(rows)


def failure_groups(results: list[Result]) -> str:
    """The failing cases grouped by (failure, command), most first, with one example each."""
    groups: dict[tuple[str, str], list[tuple[Result, str]]] = defaultdict(list)
    for r in results:
        for kind, detail in r.failures:
            groups[kind, r.case.argv[0]].append((r, detail))
    lines = []
    for (kind, command), found in sorted(groups.items(), key=lambda g: -len(g[1])):
        r, detail = found[0]
        lines.append(
            f"* {kind}, {command}: {len(found)} case(s); e.g. {r.case.id}: `aeromag "
            f"{' '.join(r.case.argv)}` → exit {r.code}: {detail}"
        )
        lines.append("  " + ", ".join(x.case.id for x, _ in found))
    return "\n".join(lines)
