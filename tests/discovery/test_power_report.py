"""The hidden-effect suite written down (``aeromag_env.discovery.power_report``): the committed
``docs/discovery/summary.md`` is what the committed summary gives, the duration tables count what
hand-made rows hold, a subset re-run picks the cases it should, and the output set holds every
file, the duration figure only with duration cases. The suite itself runs, test-sized, in
``tests/test_experiments.py`` (``experiments/hidden_effects.py --quick``, marked slow)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from aeromag_env.discovery.power import summarise
from aeromag_env.discovery.power_report import (
    DURATION_FIGURE,
    SUITE_FILES,
    in_subset,
    summary_markdown,
    write_suite,
)
from aeromag_env.discovery.suite import SINGLE

DISCOVERY = Path(__file__).resolve().parents[2] / "docs" / "discovery"
PNG = b"\x89PNG\r\n\x1a\n"


def test_the_committed_summary_md_is_what_the_committed_summary_gives():
    """``summary.md`` of the committed run (its last subset: 336 duration cases in 17.5 min on
    2 processes, as its last line says) from ``summary.json``, byte for byte."""
    s = json.loads((DISCOVERY / "summary.json").read_text())
    committed = (DISCOVERY / "summary.md").read_text()
    assert summary_markdown(s, 17.5 * 60, 2, ran=336) == committed


def _row(kind, effect=None, snr=None, named=(), duration_s=1800.0, decoys=()):
    """A hand-made row of :func:`aeromag_env.discovery.suite.run_case` (the fields
    ``summarise`` reads)."""
    truth = [[effect, None]] if effect else []
    named = [list(t) for t in named]
    return {
        "kind": kind,
        "effects": [effect] if effect else [],
        "snr": snr,
        "duration_s": duration_s,
        "named": named,
        "truth": truth,
        "exact": named == truth,
        "absorbed_named": [],
        "decoy_named": list(decoys),
        "shrink": 3.0,
    }


NM = "external_field_variation"
BASE = [_row("single", e, 2.0, [(e, None)]) for e in SINGLE] + [
    _row("null"),
    _row("coloured_null"),
]
DURATION = [
    _row("duration", NM, 0.25, [(NM, None)], 1200.0),
    _row("duration", NM, 0.25, [("altitude_gradient", None), (NM, None)], 1200.0),
    _row("duration", NM, 0.25, [], 1200.0),
    _row("duration", NM, 0.25, [("sensor_lag", None)], 3600.0, decoys=["vol_bus"]),
    _row("duration", NM, 0.5, [(NM, None)], 3600.0),
]


def test_power_against_duration_is_counted_apart_from_the_snr_claims():
    """The duration table counts a detection when the effect is among the named ones (2 of 3 at
    20 min, 0 of 1 at 60 min), and the duration flights (one with a decoy) change none of the
    SNR claims."""
    alone, both = summarise(BASE), summarise(BASE + DURATION)
    d = both.pop("power_duration")
    assert alone.pop("power_duration")["flights"] == 0
    assert both.pop("cases")["duration"] == 5
    alone.pop("cases")
    assert json.dumps(both) == json.dumps(alone)  # NaN for the empty cells: compare as text
    cell = d["power"]["0.25"][NM]
    assert (cell["1200"]["k"], cell["1200"]["n"], cell["3600"]["k"], cell["3600"]["n"]) == (
        2,
        3,
        0,
        1,
    )
    assert cell["1800"]["n"] == 0 and d["power"]["0.5"][NM]["3600"]["k"] == 1
    assert (d["flights"], d["decoy_named"]) == (5, 1)
    text = summary_markdown(summarise(BASE + DURATION), 60.0, 2, ran=5)
    row = next(line for line in text.splitlines() if line.startswith(f"| `{NM}` | 67 %"))
    assert "(2/3;" in row and "0 % (0/1;" in row and "| – |" in row
    assert text.endswith("1.0 min with 2 processes on this machine for the 5 cases of this run.\n")


@pytest.mark.parametrize(
    ("kind", "effects", "kinds", "names", "expected"),
    [
        ("single", ["sensor_lag"], ["single"], None, True),
        ("pair", ["sensor_lag", "onboard_current"], ["single"], None, False),
        ("single", ["sensor_lag"], ["single", "pair"], ["onboard_current"], False),
        ("pair", ["sensor_lag", "onboard_current"], ["pair"], ["onboard_current"], True),
        ("null", [], ["null", "single"], ["onboard_current"], True),  # nulls always match
        ("null", [], ["single"], ["onboard_current"], False),  # but only when their kind is named
    ],
)
def test_a_subset_rerun_takes_the_named_kinds_and_effects(kind, effects, kinds, names, expected):
    assert in_subset(kind, effects, kinds, names) is expected


def test_the_output_set_holds_every_file_and_the_duration_figure_only_with_its_cases(tmp_path):
    text = write_suite(BASE, tmp_path / "snr", 90.0, 2)
    written = {p.name for p in (tmp_path / "snr").iterdir()}
    assert written == set(SUITE_FILES)
    assert (tmp_path / "snr" / "summary.md").read_text() == text
    assert json.loads((tmp_path / "snr" / "results.json").read_text()) == BASE
    summary = json.loads((tmp_path / "snr" / "summary.json").read_text())
    assert summary["single_snr_ge_2"]["exact_set"]["k"] == len(SINGLE)
    write_suite(BASE + DURATION, tmp_path / "all", 90.0, 2)
    assert {p.name for p in (tmp_path / "all").iterdir()} == {*SUITE_FILES, DURATION_FIGURE}
    for name in ("confusion.png", "power.png", DURATION_FIGURE):
        png = (tmp_path / "all" / name).read_bytes()
        assert png.startswith(PNG) and len(png) > 10_000, name
