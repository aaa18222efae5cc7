"""The experiment scripts, each run as a script with ``--quick`` (or a small case) or, for tests
of their functions, loaded by path: ``experiments`` is not a package the tests import. Those
that fly more than a few flights carry the ``slow`` marker. What every script shares (its help,
its checkout, its default output) is in ``tests/test_scripts.py``; the library code behind them
has its own tests (``tests/agents/test_comparison_pipeline.py``,
``tests/discovery/test_power_report.py``, ``tests/discovery/test_plain_flights.py``)."""

import csv
import json
import subprocess

import numpy as np
import pytest

from tests._helpers import SHIPPED, experiment, run_experiment, run_script


def test_compare_methods_quick_writes_to_results_by_default(tmp_path, capsys, monkeypatch):
    from aeromag_env.compensation.compensate import METHODS

    monkeypatch.chdir(tmp_path)
    assert run_experiment("compare_methods", "--quick") == 0
    text = (tmp_path / "results" / "methods" / "table.md").read_text()
    assert text.count("\n| `") == len(METHODS)  # one row per method
    assert "`tl`" in capsys.readouterr().out


def test_choose_adaptive_defaults_quick(tmp_path, capsys):
    """The search behind the adaptive filters' defaults, on one short flight of two scenarios:
    every searched setting of every method is tried and one value chosen, and the check table
    has the baselines and the three methods."""
    out = tmp_path / "defaults.json"
    assert run_experiment("choose_adaptive_defaults", "--quick", "--out", str(out)) == 0
    found = json.loads(out.read_text())
    assert set(found["searches"]) == {"vbakf", "vbakf-pr", "imm"}
    for search in found["searches"].values():
        assert all(
            step["chosen"] in [t["value"] for t in step["tried"]] for step in search["steps"]
        )
    assert set(found["check_mean_rmse_nt"]) == {
        "kf",
        "sage-husa",
        "ding",
        "vbakf",
        "vbakf-pr",
        "imm",
    }
    assert found["check_seeds"] and max(found["seeds"] + found["check_seeds"]) < 100_000
    assert f"wrote {out}" in capsys.readouterr().out


@pytest.mark.slow
def test_evaluate_all_quick(tmp_path):
    assert run_experiment("evaluate_all", "--quick", "--out", str(tmp_path)) == 0
    matrix = (tmp_path / "matrix.md").read_text()
    assert "| fis |" in matrix and "paper" in matrix and "nominal" in matrix
    assert (tmp_path / "paper" / "results.json").exists()


def test_design_study_rule_sets_the_scales_it_states():
    """The detector schedules' actions reach the filter as the scales their docstrings state:
    Q(0), 100 × R(0), and T_p's Q at 10^10 × Q(0) only on the window after a large mean
    innovation."""
    import gymnasium as gym
    import numpy as np

    study = experiment("ppo_design_study")
    cfg = {
        **study["_detector_env"](*study["POWERS"], scale_limit=1e10),
        "scenario": "nonstationary",
    }
    env = gym.make("AeroMagCompensation-v0", config=cfg)
    obs, _ = env.reset(seed=100_000)
    rule = study["_mean_innovation_rule"](20.0, 1.5**2)
    fired = quiet = 0
    for _ in range(400):
        action = rule(obs[None])[0]
        big = obs[9] > np.log10(20.0**2 / (3 * 1.5**2))
        obs, _, _, _, info = env.step(action)
        assert info["q_scale"] == pytest.approx(1.0, rel=1e-5)
        assert info["r_scale"] == pytest.approx(100.0, rel=1e-5)
        assert info["q_permanent_scale"] == pytest.approx(1e10 if big else 1.0, rel=1e-5)
        fired, quiet = fired + big, quiet + (not big)
    assert fired > 0 and quiet > 0


@pytest.mark.slow
def test_import_time_quick(capsys):
    assert run_experiment("import_time", "--quick") == 0
    out = capsys.readouterr().out
    rows = [line for line in out.splitlines() if line.endswith(" ms")]
    assert [r[:45].strip() for r in rows] == list(experiment("import_time")["STATEMENTS"])
    assert all(float(r.split()[-2]) > 0 for r in rows)


@pytest.mark.slow
def test_own_flight_file_walkthrough(tmp_path):
    """The README's raw-XYZ walkthrough: every fault it plants is reported, the axis-swapped
    fluxgate is found, TL is fitted on the detected box and beats the vendor's channel, and the
    vendor's field is kept."""
    from aeromag_env.flight.files import read_flight

    result = experiment("own_flight_file")["walkthrough"](tmp_path)
    info = result["printed"]["info"]["printed"]
    for words in (
        "1 time gap(s)",
        "mag_1_uc: 1 spike(s)",
        "ins_pitch: 3 of",
        "119.9° from the body axes",
        "UNCOMPMAG1 → mag_1_uc",
    ):
        assert words in info, words
    tl, kf = result["reports"]["tl"], result["reports"]["kf"]
    assert all(step["exit"] == 0 for step in result["printed"].values())
    assert tl["selection"]["calibration_line"]["line"] == 1
    assert tl["held_out"]["improvement_ratio"] > tl["vendor_comparison"]["improvement_ratio_vendor"]
    assert kf["mount"]["applied"] and kf["metrics"]["nonfinite_samples"] == 3
    written = read_flight(tmp_path / "tl" / "compensated.h5")
    raw = read_flight(tmp_path / "survey_raw.xyz")
    np.testing.assert_array_equal(written["mag_1_c"], raw["mag_1_c"])
    assert np.isnan(written["aeromag_mag_1_c"]).sum() == 1  # the spike's sample, nothing else


def test_fault_effects_table(capsys):
    """The README's gap/spike/NaN table: every method within 10 % of its clean RMSE."""
    assert run_experiment("fault_effects", "--quick") == 0
    rows = [
        line
        for line in capsys.readouterr().out.splitlines()
        if line.startswith("| tl") or line.startswith("| kf")
    ]
    for row in rows:
        rmse = [float(c.split()[0]) for c in row.strip("|").split("|")[1:]]
        assert max(rmse) < 1.10 * rmse[0], row


@pytest.mark.slow
def test_seed_table_tables_each_seed_and_the_iqm(tmp_path, capsys):
    """Two "seeds" (the shipped policy and a copy) on 8 nonstationary test flights: a row each
    with the same numbers, and the IQM line (the score of both)."""
    import shutil

    copy = shutil.copy(SHIPPED["policy"], tmp_path / "seed1.npz")
    argv = [str(SHIPPED["policy"]), str(copy), "--episodes", "8", "--out", str(tmp_path)]
    assert run_experiment("seed_table", *argv) == 0
    table = (tmp_path / "table.md").read_text()
    rows = [line for line in table.splitlines() if line.startswith(("| 0 |", "| 1 |"))]
    assert len(rows) == 2 and rows[0].split("|")[3:] == rows[1].split("|")[3:]
    score = rows[0].split("|")[4].split()[0]
    assert f"IQM of the normalized score over 2 seed(s) × 1 scenario(s): {score}" in table
    assert "SD 0 nT" in table and "privileged" in table


@pytest.mark.slow
def test_seed_table_checks_a_policy_across_scenarios(tmp_path):
    """With several scenarios the table adds, per seed, the mean RMSE over them against
    ``fis``'s and the scenarios where the policy is worse than ``tuned_constant`` beyond the
    paired interval — here the shipped ``nonstationary`` policy, which on ``paper`` keeps the
    paper's tiny R and is far worse than the tuned constant."""
    argv = [
        str(SHIPPED["policy"]),
        "--scenarios",
        "paper,nonstationary",
        "--episodes",
        "4",
        "--out",
        str(tmp_path),
    ]
    assert run_experiment("seed_table", *argv) == 0
    table = (tmp_path / "table.md").read_text()
    row = next(line for line in table.splitlines() if line.startswith("| 0 | ") and "%" in line)
    assert "paper (+" in row  # ppo keeps paper's tiny R: 20 nT against the tuned 1.1
    assert "fis's mean over the 2 scenarios" in table
    assert "| beyond a bootstrap CI only |" in table and row.count("|") == 6


def test_the_bootstrap_interval_flags_what_a_few_bad_flights_hide_from_the_t_interval():
    """Differences that are small and positive on most flights and large on two: the t interval
    spans zero, the percentile bootstrap does not; a single flight has no interval."""
    from agents.evaluation.statistics import ci95

    _bootstrap_low = experiment("seed_table")["_bootstrap_low"]

    diff = np.array([0.1] * 28 + [5.0, 6.0])
    assert ci95(diff)[0] < 0 < _bootstrap_low(diff)
    assert _bootstrap_low(diff - 1.0) < 0
    assert _bootstrap_low(np.array([3.0])) == -np.inf
    assert _bootstrap_low(np.full(5, 0.2)) == 0.2


def test_same_verdicts_flags_a_changed_named_list_and_counts_unmatched(tmp_path, capsys):
    """experiments/same_verdicts.py: equal named sets (in any order) pass; a changed one fails
    with exit 1 and is printed; a case only in the new run is counted, not compared."""

    def same_verdicts(argv: list[str]) -> int:
        return run_experiment("same_verdicts", *argv)

    def row(seed, named, gap=1.0):
        return {
            "kind": "single",
            "seed": seed,
            "named": named,
            "gap_before_nt": 2.0,
            "gap_after_nt": gap,
        }

    old = [row(1, [["a", None], ["b", "ch"]]), row(2, [])]
    same = [row(1, [["b", "ch"], ["a", None]], gap=1.0 + 1e-9), row(2, []), row(3, [["a", None]])]
    changed = [row(1, [["a", None]]), row(2, [])]
    paths = {}
    for name, rows in (("old", old), ("same", same), ("changed", changed)):
        paths[name] = tmp_path / f"{name}.json"
        paths[name].write_text(json.dumps(rows))
    assert same_verdicts([str(paths["old"]), str(paths["same"])]) == 0
    out = capsys.readouterr().out
    assert "2 cases compared (1 unmatched): 0 name different effects" in out
    assert "at most 1.0e-09" in out
    assert same_verdicts([str(paths["old"]), str(paths["changed"])]) == 1
    assert "single seed 1:" in capsys.readouterr().out
    assert same_verdicts([str(paths["old"])]) == 2


def _lagged_row(out: str, window: int) -> list[float]:
    """The numbers of the lagged-privileged table's row for the decision window ``window``."""
    row = next(line for line in out.splitlines() if line.startswith(f"| {window} |"))
    return [float(cell) for cell in row.strip("|").split("|")[1:]]


def test_lagged_privileged_pays_for_knowing_the_noise_one_window_late(capsys):
    """On manoeuvre_heavy the privileged policy that sets R from the window just flown is worse
    than the one that knows the coming window (the flex noise moves within a second); --quick
    flies the first K of ``--windows`` on 2 flights."""
    assert run_experiment("lagged_privileged", "--quick", "--windows", "10,5") == 0
    out = capsys.readouterr().out
    now, late, _ = _lagged_row(out, 10)
    assert late > now and "2 validation flights" in out and "| 5 |" not in out


def test_lagged_privileged_with_a_floor_on_r_keeps_a_late_burst_out(capsys):
    """On noise_bursts the late policy lets the first window of each burst in at a small R;
    held at R ≥ 10² R(0) it loses far less (the teacher the general policy's cloning follows)."""
    argv = ["--quick", "--scenario", "noise_bursts", "--windows", "10", "--floors", "2"]
    assert run_experiment("lagged_privileged", *argv) == 0
    out = capsys.readouterr().out
    _, late, _, floored = _lagged_row(out, 10)
    assert floored < late - 0.5
    assert "late, R ≥ 10^2 R(0)" in out and out.count("|---") == 5
    assert run_experiment("lagged_privileged", "--floors", "high") == 2
    assert "--floors 'high'" in capsys.readouterr().err


def test_filter_faults_quick_counts_the_spike_it_rejects(capsys):
    assert run_experiment("filter_faults", "--quick") == 0
    out = capsys.readouterr().out
    assert out.splitlines()[0] == "| fault | kf | fakf |"
    spike = next(line for line in out.splitlines() if line.startswith("| 1e6 nT spike |"))
    assert spike.count("(1 / 0)") == 2  # one outlier rejected by each filter, no divergence
    assert "300-s nominal flight" in out


@pytest.mark.slow
def test_tune_constants_quick_writes_its_table_not_the_shipped_one(tmp_path, capsys):
    from agents.policies.tuned_table import TABLE

    shipped = TABLE.read_bytes()
    out = tmp_path / "table.json"
    assert (
        run_experiment("tune_constants", "--quick", "--scenarios", "nominal", "--out", str(out))
        == 0
    )
    table = json.loads(out.read_text())
    assert TABLE.read_bytes() == shipped
    assert set(table) == set(json.loads(shipped)) and table["paper"] == json.loads(shipped)["paper"]
    assert table["nominal"]["seeds"] == [0, 1] and len(table["nominal"]["grid_log10_q"]) == 5
    assert f"wrote {out}" in capsys.readouterr().out


def test_hidden_effects_only_needs_the_run_it_replaces_cases_in(tmp_path, capsys):
    argv = ["--quick", "--only", "null", "--out", str(tmp_path)]
    assert run_experiment("hidden_effects", *argv) == 2
    assert f"{tmp_path}/results.json, which does not exist" in capsys.readouterr().err


def _ok(done: subprocess.CompletedProcess[str]) -> str:
    """What a script run by :func:`run_script` printed, once it is seen to have exited 0."""
    assert done.returncode == 0, done.stderr[-3000:]
    return done.stdout


@pytest.mark.slow
def test_hidden_effects_quick_and_a_subset_rerun(tmp_path):
    """Nine flights on two processes: every claim's row; then the null flight again (``--only
    null``, in one process): the other rows kept, the summary made from all of them."""
    _ok(run_script("hidden_effects", "--quick", "--jobs", "2", "--out", str(tmp_path)))
    first = json.loads((tmp_path / "results.json").read_text())
    text = (tmp_path / "summary.md").read_text()
    assert "Cases: null 1, coloured_null 1, single 7." in text
    assert "| single effects at SNR ≥ 2, exact set named | ≥ 90 % |" in text
    argv = ["--quick", "--only", "null", "--jobs", "1", "--out", str(tmp_path)]
    assert "wrote" in _ok(run_script("hidden_effects", *argv))
    again = json.loads((tmp_path / "results.json").read_text())
    assert [(r["kind"], r["seed"]) for r in again] == [
        *((r["kind"], r["seed"]) for r in first if r["kind"] != "null"),
        ("null", 0),
    ]
    assert again[-1] == next(r for r in first if r["kind"] == "null")  # seeded: the same row
    assert "for the 1 cases of this run" in (tmp_path / "summary.md").read_text()


@pytest.mark.slow
def test_discovery_nominal_quick_from_another_folder(tmp_path):
    """Four plain flights, the script started in an empty folder: its rows and summary land in
    that folder's ``results/discovery``."""
    _ok(run_script("discovery_nominal", "--quick", cwd=tmp_path))
    out = tmp_path / "results" / "discovery"
    rows = json.loads((out / "nominal.json").read_text())
    assert [r["preset"] for r in rows] == ["nominal", "nominal", "paper", "noise_free"]
    text = (out / "nominal.md").read_text()
    assert "* flights: 4 (nominal 2, paper 1, noise_free 1); refused: 0" in text


@pytest.mark.slow
def test_discovery_calibration_geology_and_ground_quick():
    out = _ok(run_script("discovery_calibration", "--quick"))
    assert "null flights: 2; spurious slow groups" in out
    out = _ok(run_script("discovery_geology", "--quick"))
    assert "| 0 | 91000 |" in out and "| 50 | 91000 |" in out and "`onboard_current`" in out
    out = _ok(run_script("discovery_ground", "--quick"))
    assert "| 0 | " in out and "| `onboard_current` | 50 | " in out
    assert "| plain | 98000 | 50 |" in _ok(run_script("discovery_ground", "--low", "--quick"))


@pytest.mark.slow
def test_ppo_design_study_quick(tmp_path, capsys):
    for step in ("headroom", "detector", "shift"):
        assert run_experiment("ppo_design_study", step, "--quick") == 0, step
    out = capsys.readouterr().out
    assert "fis " in out and "detector, |mean innovation|" in out and "20 nT rule" in out
    policy = tmp_path / "trial.npz"
    assert run_experiment("ppo_design_study", "trial", "--quick", "--out", str(policy)) == 0
    assert policy.exists() and f"wrote {policy}" in capsys.readouterr().out


@pytest.mark.slow
def test_train_ppo_quick(tmp_path, capsys):
    assert run_experiment("train_ppo", "--quick", "--out", str(tmp_path)) == 0
    assert (tmp_path / "comparison.md").exists() and (tmp_path / "train" / "policy.npz").exists()
    assert "min in all" in capsys.readouterr().out


@pytest.mark.slow
def test_compare_learners_quick_trains_evaluates_selects_and_ships(tmp_path, capsys):
    """The four steps, test-sized, on one CMA-ES run: its minutes printed, the data the
    statistics read, the choice, and the policy shipped where ``--to`` says."""
    from agents.comparison.statistics import flight_table

    runs = str(tmp_path / "runs")
    train = ["train", "--learners", "cmaes", "--seeds", "0", "--quick", "--runs", runs]
    assert run_experiment("compare_learners", *train) == 0
    assert "cmaes seed 0: trained, " in capsys.readouterr().out
    assert run_experiment("compare_learners", *train) == 0  # finished: not trained again
    assert "cmaes seed 0: finished before" in capsys.readouterr().out
    assert run_experiment("compare_learners", "evaluate", "--quick", "--runs", runs) == 0
    data = tmp_path / "runs" / "data"
    with open(data / "flights.csv", newline="") as fh:
        table = flight_table(csv.DictReader(fh))
    assert table.seeds == {"cmaes": (0,)} and table.flights.shape[1] == 2
    meta = json.loads((data / "runs.json").read_text())
    assert meta["command"].startswith("python -m experiments.compare_learners evaluate --quick")
    assert (data / "policies" / "cmaes_seed0.npz").exists()
    assert run_experiment("compare_learners", "select", "--quick", "--runs", runs) == 0
    selection = json.loads((data / "selection.json").read_text())
    assert selection["chosen"] == {"learner": "cmaes", "seed": 0}
    target = tmp_path / "general.npz"
    assert run_experiment("compare_learners", "ship", "--runs", runs, "--to", str(target)) == 0
    assert target.exists() and f"wrote {target}: cmaes seed 0" in capsys.readouterr().out


def test_fault_suite_quick_takes_one_case_per_class_and_command(capsys):
    assert run_experiment("fault_suite", "--quick", "--list") == 0
    listed = capsys.readouterr().out.splitlines()
    pairs = [(line.split("/")[0], line.split(": aeromag ")[1].split()[0]) for line in listed]
    assert len(pairs) == len(set(pairs)) > 10


def test_calibrate_then_apply_quick(tmp_path, capsys):
    assert run_experiment("calibrate_then_apply", "--quick", "--out", str(tmp_path)) == 0
    result = json.loads((tmp_path / "results.json").read_text())
    summary = result["summary"]
    assert summary["pairs"] == 3
    warnings = summary["recalibrate_warnings"]
    assert warnings["tl"] == {"survey": 0, "survey_geology": 0, "other": 3, "changed": 3}
    assert warnings["kf"]["survey"] == 0 and warnings["kf"]["other"] == 3
    comparison = summary["tl_rmse_nt"]["calibrated_minus_fitted_on_survey"]
    low, high = comparison["ci95"]
    assert low <= comparison["mean_difference"] <= high
    # over geology the survey's own fit absorbs the anomaly: calibration is better in every pair;
    # the filter continued from the calibrated state is better than a cold one in every pair
    assert (
        summary["tl_rmse_nt_geology"]["calibrated_minus_fitted_on_survey"]["pairs_a_at_most_b"] == 3
    )
    assert summary["kf_warm_minus_cold_first_60_s"]["pairs_a_at_most_b"] == 3


def test_magnav_tl_check_on_a_file_in_magnavs_layout(tmp_path):
    """experiments/magnav_tl_check.py on a synthetic file laid out as MagNav.jl's
    test_data_TL.mat (a TL_data struct of column vectors, fields of other lengths beside them):
    calibrate then compensate --model equals compensate --method tl, and MagNav's own numbers
    (here made with this package's Tolles–Lawson at MagNav's settings) are compared."""
    import scipy.io

    from aeromag_env.compensation.tolles_lawson import TollesLawson
    from aeromag_env.simulation.config import preset, with_overrides
    from aeromag_env.simulation.simulate import simulate_flight
    from aeromag_env.simulation.tolles_lawson_terms import design_matrix

    cfg = with_overrides(preset("nominal"), {"trajectory.duration_s": 100.0})
    flight = simulate_flight(cfg, 4)
    flux, mag = flight.vector("flux_a"), flight["mag_1_uc"]
    check = experiment("magnav_tl_check")
    tl = TollesLawson(ridge=check["MAGNAV_RIDGE"]).fit(flux, mag, flight.sample_rate_hz)
    column = {name: flight[name][:, None] for name in check["CHANNELS"]}
    struct = {
        "fs": float(flight.sample_rate_hz),
        **column,
        "A_a": design_matrix(flux),
        "A_a_f_t": np.zeros((flight.n - 40, 18)),  # another length, as MagNav's filtered arrays
        "TL_a_1": tl.coef_[:, None],
        "mag_1_c": (mag - design_matrix(flux) @ tl.coef_)[:, None],
    }
    path = tmp_path / "test_data_TL.mat"
    scipy.io.savemat(path, {"TL_data": struct})
    assert run_experiment("magnav_tl_check", str(path), "--out", str(tmp_path)) == 0
    result = json.loads((tmp_path / "magnav_tl_check.json").read_text())
    assert result["samples"] == flight.n == result["compared_samples"]
    assert result["equal_within_1e-9_nt"] and result["same_flagged_samples"]
    assert result["coefficients_max_relative_difference_to_magnav"] < 1e-9  # the same fit
    assert result["compensated_difference_std_to_magnav_nt"] < 1e-9  # a constant apart


def test_the_calibrate_howto_quotes_its_results_file():
    """docs/howto/calibrate.md's table is the one its committed results file gives."""
    from tests._helpers import ROOT

    results = json.loads((ROOT / "docs" / "howto" / "calibrate_then_apply.json").read_text())
    table = experiment("calibrate_then_apply")["markdown_table"](results["summary"])
    assert table in (ROOT / "docs" / "howto" / "calibrate.md").read_text()
    assert results["summary"]["pairs"] >= 10


def test_general_tuner_bounds_summary_on_made_up_flights():
    """The summary's hindsight minimum is per flight, the blind row is the lowest geometric
    mean ratio, and a scenario without headroom gets no score."""
    summarise = experiment("general_tuner_bounds")["summarise"]
    flights = {
        "a": {  # headroom 1 nT on every flight
            "tuned_constant": [2.0, 2.0, 2.2],
            "privileged": [1.0, 1.0, 1.2],
            "constant:a": [2.0, 2.0, 2.2],
            "constant:b": [4.0, 1.5, 4.2],
        },
        "b": {  # no headroom
            "tuned_constant": [1.0, 1.1, 1.0],
            "privileged": [1.0, 1.1, 1.0],
            "constant:a": [3.0, 3.3, 3.0],
            "constant:b": [1.0, 1.1, 1.0],
        },
    }
    s = summarise(flights)
    a = s["scenarios"]["a"]
    assert a["mean_rmse_nt"]["hindsight_best_constant"] == pytest.approx((2.0 + 1.5 + 2.2) / 3)
    assert a["score"]["hindsight_best_constant"] == pytest.approx((6.2 - 5.7) / 3 / 1.0)
    assert s["scenarios"]["b"]["score"]["privileged"] is None
    # row a: ratios 1 and 3; row b: 1.57 and 1: the geometric means 1.73 and 1.25
    assert s["best_blind_row"] == "constant:b"
    assert s["iqm"]["privileged"] == pytest.approx(1.0)


@pytest.mark.slow
def test_general_tuner_bounds_quick(tmp_path):
    out = tmp_path / "bounds.json"
    assert "wrote" in _ok(run_script("general_tuner_bounds", "--quick", "--out", str(out)))
    result = json.loads(out.read_text())
    assert len(result["seeds"]) == 2 and len(result["flights"]) == 2
    first = next(iter(result["flights"].values()))
    assert {"tuned_constant", "privileged", "imm", "vbakf"} <= set(first)
