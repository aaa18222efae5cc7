"""The HTML reports (:mod:`aeromag_env.reports`): built from plain data, self-contained, light
for long flights (decimation keeps every spike), written with the output set; and, with the
``browser`` marker (``pytest -m browser``, its own CI step), opened in headless Chromium: no
console error, every plot drawn, the headline figures equal to ``report.json``'s, no request
leaving the page. The browser tests save the screenshots of docs/reports/."""

from __future__ import annotations

import csv
import json
import subprocess
import sys
from html.parser import HTMLParser
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from aeromag_env import reports
from aeromag_env.cli.main import main
from aeromag_env.flight.files import write_flight
from aeromag_env.reports.decimate import extreme_indices, time_gaps, with_breaks
from aeromag_env.reports.html import lookup
from tests._flights import simulated

ROOT = Path(__file__).resolve().parents[2]
SHOTS = ROOT / "docs" / "reports"
#: Sample rate of the synthetic flights [Hz] (the simulator's default).
FS_HZ = 10.0
#: A page, whatever the flight's length, stays under this [bytes]: BokehJS (~1.3 MB) and
#: ~2000 columns × 2 extremes per series.
MAX_PAGE_BYTES = 4_000_000


def synthetic_arrays(hours: float, seed: int = 0) -> dict[str, np.ndarray]:
    """A compensated flight's arrays without running a filter: a box track, interference as a
    sine, noise, a 5000-nT spike, a time gap and five non-finite samples."""
    rng = np.random.default_rng(seed)
    n = int(hours * 3600 * FS_HZ)
    tt = np.arange(n) / FS_HZ
    tt[n // 2 :] += 120.0  # a two-minute gap
    model = 53_000.0 + 0.01 * tt
    interference = 300.0 * np.sin(tt / 50.0)
    before = model + interference + rng.normal(0.0, 1.0, n)
    after = model + rng.normal(0.0, 0.5, n)
    spike = n // 3
    before[spike] += 5000.0
    spikes = np.zeros(n, dtype=bool)
    spikes[spike] = True
    nonfinite = np.zeros(n, dtype=bool)
    nonfinite[n - 100 : n - 95] = True
    after[nonfinite] = np.nan
    heading = np.floor(tt / 600.0) * np.pi / 2
    east = np.cumsum(60.0 * np.sin(heading)) / FS_HZ
    north = np.cumsum(60.0 * np.cos(heading)) / FS_HZ
    walk = np.exp(np.cumsum(rng.normal(0.0, 0.01, (n, 2)), axis=0))
    return {
        "tt": tt,
        "total_before": before,
        "total_after": after,
        "model_total": model,
        "lat": 45.0 + north / 111_000.0,
        "lon": -75.0 + east / 78_000.0,
        "spikes": spikes,
        "nonfinite": nonfinite,
        "ror": np.exp(rng.normal(0.0, 0.3, n)),
        "qoq": np.exp(rng.normal(0.0, 0.3, n)),
        "q_scale": walk[:, 0],
        "r_scale": walk[:, 1],
        "interference_true": np.column_stack([interference] * 3),
        "interference_estimated": np.column_stack([interference] * 3) + rng.normal(0, 1, (n, 3)),
        "maneuvers": np.array([[100.0, 130.0], [200.0, 230.0]]),
    }


REPORT = {
    "input": "synthetic.h5",
    "method": "fakf",
    "metrics": {
        "compensation_rmse_nt": 2.52542138010139,
        "improvement_ratio": 10.771242008582684,
        "fom_nt": 85.60879053239755,
        "divergences": 0,
        "nonfinite_samples": 5,
    },
    "coefficients": {"permanent_nt": [292.6, -185.8, 155.8], "induced": np.eye(3).tolist()},
    "nonfinite_policy": "skipped by the filter",
    "input_problems": ["5 non-finite samples in flux_a"],
    "input_sha256": "d9b6",
}


class _Links(HTMLParser):
    """Every src/href attribute outside the scripts' text, and the script/link elements."""

    def __init__(self) -> None:
        super().__init__()
        self.urls: list[str] = []
        self.keyed: dict[str, str] = {}

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        found = dict(attrs)
        self.urls += [v or "" for k, v in attrs if k in ("src", "href")]
        if found.get("data-key") is not None:
            self.keyed[found["data-key"] or ""] = found.get("data-value") or ""


def parse(page: str) -> _Links:
    links = _Links()
    links.feed(page)
    return links


def assert_self_contained(page: str) -> None:
    """No src/href to another host (or protocol-relative), no external script or style."""
    links = parse(page)
    remote = [u for u in links.urls if u.startswith(("http://", "https://", "//"))]
    assert remote == [], remote
    assert "<script src" not in page and '<link rel="stylesheet"' not in page


def assert_headlines_match(page: str, report: dict[str, Any]) -> int:
    """Every ``data-key`` of the page holds the report's value at that key; returns how many."""
    keyed = parse(page).keyed
    for key, raw in keyed.items():
        assert json.loads(raw) == lookup(report, key), key
    return len(keyed)


# --- decimation ---------------------------------------------------------------------------


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_a_single_sample_spike_survives_decimation(sign: float) -> None:
    rng = np.random.default_rng(3)
    y = rng.normal(0.0, 1.0, 360_000)  # 10 h at 10 Hz
    where = int(rng.integers(y.size))
    y[where] += sign * 50.0
    idx = extreme_indices(y, 2000)
    assert where in idx
    assert idx.size <= 3 * 2000
    assert np.all(np.diff(idx) > 0)


def test_decimation_keeps_each_columns_extremes_and_marks_gaps() -> None:
    rng = np.random.default_rng(4)
    y = rng.normal(0.0, 1.0, 10_000)
    y[5000:5010] = np.nan
    idx = extreme_indices(y, 100)
    for column in np.array_split(np.arange(y.size), 100):  # 100 samples each
        kept = np.intersect1d(idx, column)
        vals = y[column]
        assert np.nanmax(vals) in y[kept] and np.nanmin(vals) in y[kept]
    assert np.isnan(y[idx]).sum() >= 1  # the line breaks at the NaN run
    tt = np.arange(y.size, dtype=float)
    tt[7000:] += 500.0
    gaps = time_gaps(tt)
    assert gaps.tolist() == [6999]
    x, (yd,) = with_breaks(tt, [np.nan_to_num(y)], idx, gaps)
    k = int(np.flatnonzero(x == tt[6999])[-1])
    assert np.isnan(yd[k]) and x[k + 1] >= tt[7000]  # a break between the two sides


# --- the pages ----------------------------------------------------------------------------


def test_import_of_the_package_and_the_reports_does_not_load_bokeh() -> None:
    code = "import sys, aeromag_env, aeromag_env.reports; print('bokeh' in sys.modules)"
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert run.stdout.strip() == "False"


def test_a_compensate_page_is_self_contained_and_shows_the_report() -> None:
    page = reports.compensate_page(REPORT, synthetic_arrays(0.1))
    assert_self_contained(page)
    assert assert_headlines_match(page, REPORT) >= 4
    assert "5 non-finite samples in flux_a" in page  # the warning, as text
    assert page == reports.compensate_page(REPORT, synthetic_arrays(0.1))  # same bytes


@pytest.fixture(scope="module")
def sizes() -> dict[float, int]:
    return {h: len(reports.compensate_page(REPORT, synthetic_arrays(h)).encode()) for h in (1, 10)}


def test_a_long_flight_page_stays_light(sizes: dict[float, int]) -> None:
    print(f"page sizes: 1 h {sizes[1] / 1e6:.2f} MB, 10 h {sizes[10] / 1e6:.2f} MB")
    assert sizes[10] < MAX_PAGE_BYTES
    assert sizes[10] < 1.3 * sizes[1]  # decimated: hardly grows with the length


def evaluate_results() -> dict[str, Any]:
    rng = np.random.default_rng(5)
    seeds = list(range(100_000, 100_006))
    policies = {}
    for k, name in enumerate(("constant", "fis", "tuned_constant", "oracle")):
        rmse = np.exp(rng.normal(1.0 - 0.3 * k, 0.2, len(seeds)))
        m = float(rmse.mean())
        policies[name] = {
            "rmse_nt_mean": m,
            "rmse_nt_ci95": [m * 0.9, m * 1.1],
            "divergences": k,
            "rmse_nt": rmse.tolist(),
            "normalized_score": k / 2.0 - 0.5,
            "normalized_score_ci95": [k / 2.0 - 0.7, k / 2.0 - 0.3],
        }
    return {
        "scenario": "nominal",
        "seeds": seeds,
        "policies": policies,
        "normalized_score": {"zero": "fis", "one": "oracle", "note": ""},
    }


def evaluate_traces() -> dict[str, dict[str, np.ndarray]]:
    rng = np.random.default_rng(6)
    t = np.arange(1, 201) * 5.0
    return {
        name: {
            "t": t,
            "q_scale": np.exp(np.cumsum(rng.normal(0, 0.1, t.size))),
            "r_scale": np.exp(np.cumsum(rng.normal(0, 0.1, t.size))),
            "seed": np.array([100_000]),
        }
        for name in ("constant", "fis", "oracle")
    }


def training_summary() -> dict[str, Any]:
    curve = [
        {"timesteps": k * 2048, "validation_rmse_nt": 5.0 / (1 + k), "seconds": 30.0 * k}
        for k in range(12)
    ]
    return {
        "scenario": "nominal",
        "timesteps": 11 * 2048,
        "best_validation_rmse_nt": 5.0 / 12,
        "curve": curve,
    }


def discover_inputs() -> tuple[dict[str, Any], dict[str, np.ndarray], list[Any]]:
    rng = np.random.default_rng(7)
    n = 6000
    tt = np.arange(n) / FS_HZ
    current = np.abs(np.sin(tt / 40.0)) * 10.0
    after = rng.normal(0.0, 1.0, (n, 3))
    before = after + np.outer(current, [3.0, 0.5, 0.1])
    series = {
        "tt": tt,
        "residual_before": before,
        "residual_after": after,
        "held_out": (tt % 180) >= 120,
    }
    report = {
        "input": "synthetic.h5",
        "verdict": "missing effects named",
        "gap": {
            "rms_before_nt": 12.5,
            "rms_after_nt": 1.02,
            "shrink": 12.25,
            "white_noise_floor_nt": 1.0,
            "held_out_scheme": "every third 60-s block",
        },
        "caveats": ["the flight has no calibration box"],
        "missing_effects": [
            {
                "name": "current",
                "channel": "cur_strb",
                "evidence": {"f_statistic": 900.0, "log10_p_value": -300.0, "delta_bic": -2500},
                "held_out_gap": {"rms_without_nt": 12.5, "rms_with_nt": 1.02},
            }
        ],
        "candidates": [
            {"name": "current", "channel": "cur_strb", "verdict": "added", "regressors": 3},
            {"name": "lag", "channel": None, "verdict": "absorbed", "regressors": 3},
        ],
        "skipped": [],
        "data": {"samples": n},
    }
    return report, series, [("current", "cur_strb", current)]


def fleet_rows() -> list[dict[str, Any]]:
    return [
        {
            "file": f"flights/f{k}.h5",
            "output": f"f{k}",
            "status": "ok" if k != 2 else "error",
            "method": "fakf",
            "std_uncompensated_nt": 3.5 + k,
            "std_compensated_nt": 0.3 + 0.1 * k if k != 2 else None,
            "improvement_ratio": 10.0 - k if k != 2 else None,
            "fom_nt": 80.0 + k if k != 2 else None,
            "warnings": k % 2,
            "warning_text": "a warning" if k % 2 else "",
            "error": "not HDF5" if k == 2 else "",
            "attempts": 1,
        }
        for k in range(5)
    ]


def all_pages() -> dict[str, tuple[str, dict[str, Any]]]:
    """Each kind of page and the report its headline figures come from."""
    from aeromag_env.jobs.fleet import COMPENSATE_COLUMNS

    results = evaluate_results()
    training = training_summary()
    disc, series, drivers = discover_inputs()
    rows = fleet_rows()
    fleet_report = {"flights": 5, "failed": 1, "with_warnings": 2}
    return {
        "compensate": (reports.compensate_page(REPORT, synthetic_arrays(0.25)), REPORT),
        "discover": (reports.discover_page(disc, series, drivers), disc),
        "evaluate": (reports.evaluate_page(results, evaluate_traces()), results),
        "train": (reports.train_page({"run": training}), training),
        "fleet": (
            reports.fleet_page(rows, COMPENSATE_COLUMNS, "compensate", "report.html"),
            fleet_report,
        ),
    }


def test_every_kind_of_page_is_self_contained_with_the_reports_figures() -> None:
    for kind, (page, report) in all_pages().items():
        assert_self_contained(page)
        assert assert_headlines_match(page, report) >= 1, kind


# --- written with the output set ----------------------------------------------------------


@pytest.fixture(scope="module")
def short_flight(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("html") / "flight.h5"
    write_flight(simulated(trajectory__duration_s=600.0), path)
    return path


def test_compensate_writes_report_html_with_the_set_and_no_html_writes_none(
    tmp_path: Path, short_flight: Path
) -> None:
    out = tmp_path / "out"
    assert main(["compensate", str(short_flight), "--method", "lsq", "--out", str(out)]) == 0
    page = (out / "report.html").read_text(encoding="utf-8")
    report = json.loads((out / "report.json").read_text())
    assert_self_contained(page)
    assert assert_headlines_match(page, report) >= 3
    assert "estimated interference per axis" in page  # a simulated flight has the truth
    bare = tmp_path / "bare"
    argv = ["compensate", str(short_flight), "--method", "lsq", "--no-html", "--out", str(bare)]
    assert main(argv) == 0
    assert sorted(p.name for p in bare.iterdir()) == [
        "compensated.h5",
        "compensation.png",
        "report.json",
    ]


def test_a_failing_page_replaces_nothing_of_the_set(
    tmp_path: Path, short_flight: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    out = tmp_path / "out"
    assert main(["compensate", str(short_flight), "--method", "lsq", "--out", str(out)]) == 0
    before = {p.name: p.read_bytes() for p in out.iterdir()}

    def broken(*_args: Any, **_kwargs: Any) -> str:
        raise RuntimeError("page failed")

    monkeypatch.setattr(reports, "compensate_page", broken)
    assert main(["compensate", str(short_flight), "--method", "kf", "--out", str(out)]) == 1
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before  # the old set, whole


# --- in a real browser --------------------------------------------------------------------


def flawed_flight(folder: Path, seed: int = 1) -> Path:
    """A 15-minute simulated calibration flight with what real files have: a 3000-nT spike in
    the fluxgate, five NaN attitude samples and a 30-s recording gap."""
    from aeromag_env.flight.data import Flight

    flight = simulated(trajectory__duration_s=900.0, seed=seed)
    fields = {k: np.array(v, copy=True) for k, v in flight.fields.items()}
    n = fields["tt"].size
    fields["flux_a_x"][n // 3] += 3000.0
    fields["ins_roll"][2 * n // 3 : 2 * n // 3 + 5] = np.nan
    fields["tt"][n // 2 :] += 30.0
    return write_flight(Flight(fields, dict(flight.attrs)), folder / f"flight{seed}.h5")


@pytest.fixture(scope="module")
def real_pages(tmp_path_factory: pytest.TempPathFactory) -> dict[str, tuple[Path, dict[str, Any]]]:
    """Each kind of page as the commands write it, with the report its figures come from (the
    training curve is a made-up one: a training run is too long for a test)."""
    root = tmp_path_factory.mktemp("pages")
    flights = root / "flights"
    flights.mkdir()
    flight = flawed_flight(flights)
    flawed_flight(flights, seed=2)
    (flights / "broken.h5").write_text("not a flight\n")
    out = {kind: root / kind for kind in ("compensate", "discover", "evaluate", "fleet", "train")}
    assert (
        main(["compensate", str(flight), "--method", "fakf", "--out", str(out["compensate"])]) == 0
    )
    assert main(["discover", str(flight), "--quiet", "--out", str(out["discover"])]) == 0
    policies = "constant,fis,tuned_constant,oracle"
    argv = ["evaluate", "--scenario", "nominal", "--policies", policies, "--episodes", "3"]
    assert main([*argv, "--quiet", "--out", str(out["evaluate"])]) == 0
    assert main(["compensate", str(flights), "--method", "lsq", "--out", str(out["fleet"])]) == 2
    out["train"].mkdir()
    (out["train"] / "report.html").write_text(reports.train_page({"run": training_summary()}))
    (out["train"] / "training.json").write_text(json.dumps(training_summary()))
    rows = list(csv.DictReader((out["fleet"] / "fleet.csv").open()))
    fleet_report = {
        "flights": len(rows),
        "failed": sum(r["status"] != "ok" for r in rows),
        "with_warnings": sum(1 for r in rows if r["warnings"] not in ("", "0")),
    }
    return {
        "compensate": (out["compensate"] / "report.html", _json(out["compensate"] / "report.json")),
        "discover": (out["discover"] / "report.html", _json(out["discover"] / "report.json")),
        "evaluate": (out["evaluate"] / "report.html", _json(out["evaluate"] / "results.json")),
        "train": (out["train"] / "report.html", training_summary()),
        "fleet": (out["fleet"] / "index.html", fleet_report),
    }


def _json(path: Path) -> dict[str, Any]:
    return json.loads(path.read_text(encoding="utf-8"))


@pytest.mark.browser
@pytest.mark.parametrize("kind", ["compensate", "discover", "evaluate", "train", "fleet"])
def test_each_kind_of_page_renders_in_chromium(
    kind: str, real_pages: dict[str, tuple[Path, dict[str, Any]]], chromium: Any
) -> None:
    from tests import _browser

    path, report = real_pages[kind]
    _browser.open_page(chromium, path)
    assert _browser.console_errors(chromium) == []
    outside = [u for u in _browser.requests(chromium) if not u.startswith(("file:", "data:"))]
    assert outside == []
    links = chromium.execute_script(_browser.LINKS_JS)
    assert [u for u in links if u.startswith(("http:", "https:", "//"))] == []
    plots = chromium.execute_script(_browser.PLOTS_JS)
    figures = [p for p in plots["plots"] if p["type"] != "DataTable"]
    assert figures and {p["id"] for p in plots["plots"]} <= set(plots["views"])
    drawn = [
        c
        for c in chromium.execute_script(_browser.CANVASES_JS)
        if c["height"] >= 100 and c["width"] >= 200 and c["inked"] > 0.002
    ]
    assert len(drawn) >= len(figures)  # every plot's canvas has ink
    shown = chromium.execute_script(
        "return [...document.querySelectorAll('[data-key]')].map("
        "e => [e.dataset.key, e.dataset.value, e.querySelector('.v') ? "
        "e.querySelector('.v').firstChild.textContent.trim() : e.textContent.trim()]);"
    )
    assert shown
    for key, raw, text in shown:
        value = lookup(report, key)
        assert json.loads(raw) == value, key
        assert reports.html.number(value) in text, (key, text)  # as people see it
    if kind == "fleet":
        rows = list(csv.DictReader((path.parent / "fleet.csv").open()))
        table = chromium.execute_script(
            "const t = Bokeh.documents[0].get_model_by_name('fleet_table');"
            "return [t.source.data.output, t.source.data.improvement_ratio.map("
            "v => Number.isNaN(v) ? null : v), t.source.data.link];"
        )
        assert table[0] == [r["output"] for r in rows]
        for cell, row in zip(table[1], rows, strict=True):
            assert (cell is None) == (row["improvement_ratio"] == "")
            if cell is not None:
                assert cell == pytest.approx(
                    float(row["improvement_ratio"]), rel=1e-5
                )  # csv: 6 digits
        for link in table[2]:
            assert link == "" or (path.parent / link).is_file()  # each flight's page exists
    _browser.screenshot(chromium, SHOTS / f"{kind}.png")


@pytest.fixture(scope="module")
def chromium() -> Any:
    from tests import _browser

    with _browser.browser() as driver:
        yield driver


def test_the_seeds_page_and_the_discover_fleet_index_show_their_figures() -> None:
    from aeromag_env.jobs.fleet import DISCOVER_COLUMNS

    runs = {f"seed {k}": {**training_summary(), "best_validation_rmse_nt": 0.4 + k} for k in (0, 1)}
    page = reports.train_page(runs)
    assert_self_contained(page)
    assert assert_headlines_match(page, runs) == 2  # one per seed, keyed by its label
    rows = [
        {
            "file": f"f{k}.h5",
            "output": f"f{k}",
            "status": "ok",
            "verdict": "no missing effect",
            "gap_before_nt": 1.0 + k,
            "gap_after_nt": 1.0,
            "gap_shrink": 1.0 + k,
            "warnings": 0,
        }
        for k in range(3)
    ]
    page = reports.fleet_page(rows, DISCOVER_COLUMNS, "discover", reports.PAGE)
    assert_self_contained(page)
    assert assert_headlines_match(page, {"flights": 3, "failed": 0, "with_warnings": 0}) == 3
    assert "held-out gap shrink" in page


@pytest.mark.parametrize(
    "command", ["compensate f.h5 --method kf", "discover f.h5", "evaluate", "train"]
)
def test_every_command_with_a_page_takes_no_html(command: str) -> None:
    from aeromag_env.cli.parser import build_parser

    argv = [*command.split(), "--out", "o"]
    assert build_parser().parse_args(argv).no_html is False
    assert build_parser().parse_args([*argv, "--no-html"]).no_html is True
