"""The ``report.json`` reference: the keys each command writes, read from a real run.

At build time the commands that write a ``report.json`` (``compensate``, ``discover``,
``reproduce-paper``) run on a short simulated flight with their default options, and this page
lists every key of what they wrote, with its JSON type and the value of that run; the prose is
each command module's docstring. The runs are cached under ``docs/_build/`` by a digest of the
package's source, so a rebuild without a code change does not run them again.
"""

from __future__ import annotations

import contextlib
import hashlib
import inspect
import io
import json
import re
import tempfile
from pathlib import Path
from typing import Any

from rst import heading, list_table, literal, text, write_if_changed

import aeromag_env
from aeromag_env.cli.main import main
from aeromag_env.compensation import paper
from aeromag_env.jobs import compensate, discover

#: The runs documented: command, its module (whose docstring is the prose), its arguments
#: after the flight file and the output folder.
RUNS = {
    "compensate": (compensate, ["compensate", "{flight}", "--method", "tl", "--out", "{out}"]),
    "discover": (discover, ["discover", "{flight}", "--out", "{out}"]),
    "reproduce-paper": (paper, ["reproduce-paper", "--quick", "--out", "{out}"]),
}
#: The simulated flight the commands read (the default calibration flight).
SIMULATE = ["simulate", "--seed", "1", "--quiet", "--out", "{flight}"]
_RECORD_KEY = re.compile(r"^[a-z_][a-z0-9_]*$")
_MAX_DEPTH = 3
_MAX_VALUE = 60


def source_digest() -> str:
    """SHA-256 over the package's Python sources (what the reports depend on)."""
    h = hashlib.sha256()
    for path in sorted(Path(aeromag_env.__file__).parent.rglob("*.py")):
        h.update(path.read_bytes())
    return h.hexdigest()[:16]


def reports(cache: Path) -> dict[str, dict[str, Any]]:
    """Each command's ``report.json`` (run now, or read from ``cache`` for this source)."""
    folder = cache / source_digest()
    if not all((folder / f"{name}.json").exists() for name in RUNS):
        folder.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryDirectory() as tmp:
            flight = str(Path(tmp) / "flight.h5")
            _run([a.format(flight=flight) for a in SIMULATE])
            for name, (_, argv) in RUNS.items():
                out = str(Path(tmp) / name)
                _run([a.format(flight=flight, out=out) for a in argv])
                report = json.loads((Path(out) / "report.json").read_text())
                (folder / f"{name}.json").write_text(json.dumps(report, indent=1))
    return {name: json.loads((folder / f"{name}.json").read_text()) for name in RUNS}


def _run(argv: list[str]) -> None:
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        status = main(argv)
    if status != 0:
        raise RuntimeError(f"aeromag {' '.join(argv)} exited {status}")


def key_rows(value: Any, path: str = "", depth: int = 0) -> list[tuple[str, str, str]]:
    """(key path, JSON type, value of this run) for every key of ``value``, depth first.

    Objects whose keys are data (effect names, heading bins…) are shown as one row; a list of
    objects is described by its first element (``key[]``).
    """
    rows: list[tuple[str, str, str]] = []
    if isinstance(value, dict):
        for key, item in value.items():
            sub = f"{path}.{key}" if path else key
            rows.append((sub, _json_type(item), _shown(item)))
            if depth + 1 < _MAX_DEPTH and _is_record(item):
                rows += key_rows(item, sub, depth + 1)
            elif depth + 1 < _MAX_DEPTH and isinstance(item, list) and item and _is_record(item[0]):
                rows += key_rows(item[0], sub + "[]", depth + 1)
    return rows


def _is_record(value: Any) -> bool:
    """A JSON object with fixed keys (not one keyed by data)."""
    return isinstance(value, dict) and all(_RECORD_KEY.match(k) for k in value)


def _json_type(value: Any) -> str:
    if value is None:
        return "null"
    if isinstance(value, bool):
        return "boolean"
    if isinstance(value, (int, float)):
        return "number"
    if isinstance(value, str):
        return "string"
    if isinstance(value, list):
        inner = sorted({_json_type(v) for v in value})
        return f"array of {' / '.join(inner)}" if inner else "array"
    keyed = "" if _is_record(value) else " (keys are data)"
    return "object" + keyed


def _shown(value: Any) -> str:
    if isinstance(value, (dict, list)):
        if isinstance(value, dict) and not _is_record(value) and value:
            keys = list(value)
            return "keys: " + ", ".join(keys[:3]) + (", …" if len(keys) > 3 else "")
        return "" if isinstance(value, dict) else f"{len(value)} entries"
    shown = json.dumps(value, ensure_ascii=False)
    return shown if len(shown) <= _MAX_VALUE else shown[: _MAX_VALUE - 1] + "…"


def report_page(cache: Path) -> str:
    parts = [
        ".. _report-json:\n\n",
        heading("report.json", "="),
        "\n",
        "Three commands write a ``report.json`` beside their figures: "
        + ", ".join(f":ref:`aeromag {name} <cli-{name}>`" for name in RUNS)
        + ". The tables below are generated when the documentation is built: each command runs "
        "with its default options on a simulated calibration flight "
        f"(``aeromag {' '.join(a for a in SIMULATE if '{' not in a)}``), and every key it "
        "wrote is listed with its type and the value of that run. Options add keys (for "
        "example ``discover --ground``); keys whose value is ``null`` here hold an object "
        "when they apply (``vendor_comparison`` needs the vendor's compensated channel).\n\n",
    ]
    for name, report in reports(cache).items():
        module = RUNS[name][0]
        prose = inspect.cleandoc(module.__doc__ or "")
        rows = [
            [literal(key), text(kind), literal(value) if value else ""]
            for key, kind, value in key_rows(report)
        ]
        parts += [
            f".. _report-json-{name}:\n\n",
            heading(f"aeromag {name}", "-"),
            "\n",
            f".. currentmodule:: {module.__name__}\n\n",
            prose + "\n\n",
            f"``report_version`` {report.get('report_version', '–')}. Keys ({len(rows)} rows):\n\n",
            list_table(["key", "type", "value in the documented run"], rows, "38 17 45"),
            "\n",
        ]
    return "".join(parts)


def write(out: Path, cache: Path) -> Path:
    path = out / "report-json.rst"
    write_if_changed(path, report_page(cache))
    return path
