"""The experiment scripts, each run as a script (``--quick`` or a small case) or, for tests of
their functions, loaded by path: ``experiments`` is not a package the tests import."""

import json

import numpy as np
import pytest

from tests._helpers import SHIPPED, experiment, run_experiment


def test_compare_methods_quick(tmp_path, capsys):
    from aeromag_env.compensation.compensate import METHODS

    assert run_experiment("compare_methods", "--quick", "--out", str(tmp_path)) == 0
    text = (tmp_path / "table.md").read_text()
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
        **study["DETECTOR_ENV"],
        "scenario": "nonstationary",
        "innovation_power": True,
        "scale_limit": 1e10,
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
    assert run_experiment("fault_effects", "--methods", "tl,kf") == 0
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
    from agents.evaluate import ci95

    _bootstrap_low = experiment("seed_table")["_bootstrap_low"]

    diff = np.array([0.1] * 28 + [5.0, 6.0])
    assert ci95(diff)[0] < 0 < _bootstrap_low(diff)
    assert _bootstrap_low(diff - 1.0) < 0
    assert _bootstrap_low(np.array([3.0])) == -np.inf
    assert _bootstrap_low(np.full(5, 0.2)) == 0.2


def _suite_row(kind, effect=None, snr=None, named=(), duration_s=1800.0, decoys=()):
    """A hand-made row of ``experiments/hidden_effects.py`` (the fields ``summarise`` reads)."""
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


def test_hidden_effects_counts_power_against_duration_apart_from_the_snr_claims():
    """``summarise`` on hand-made rows: the duration table counts a detection when the effect is
    among the named ones (2 of 3 at 20 min, 0 of 1 at 60 min), and the duration flights (one
    with a decoy) change none of the SNR claims."""
    import json

    hidden_effects = experiment("hidden_effects")
    SINGLE, markdown, summarise = (hidden_effects[n] for n in ("SINGLE", "markdown", "summarise"))

    nm = "external_field_variation"
    base = [_suite_row("single", e, 2.0, [(e, None)]) for e in SINGLE]
    base += [_suite_row("null"), _suite_row("coloured_null")]
    duration = [
        _suite_row("duration", nm, 0.25, [(nm, None)], 1200.0),
        _suite_row("duration", nm, 0.25, [("altitude_gradient", None), (nm, None)], 1200.0),
        _suite_row("duration", nm, 0.25, [], 1200.0),
        _suite_row("duration", nm, 0.25, [("sensor_lag", None)], 3600.0, decoys=["vol_bus"]),
        _suite_row("duration", nm, 0.5, [(nm, None)], 3600.0),
    ]
    alone, both = summarise(base), summarise(base + duration)
    d = both.pop("power_duration")
    assert alone.pop("power_duration")["flights"] == 0
    assert both.pop("cases")["duration"] == 5
    alone.pop("cases")
    assert json.dumps(both) == json.dumps(alone)  # NaN for the empty cells: compare as text
    cell = d["power"]["0.25"][nm]
    assert (cell["1200"]["k"], cell["1200"]["n"], cell["3600"]["k"], cell["3600"]["n"]) == (
        2,
        3,
        0,
        1,
    )
    assert cell["1800"]["n"] == 0 and d["power"]["0.5"][nm]["3600"]["k"] == 1
    assert (d["flights"], d["decoy_named"]) == (5, 1)
    text = markdown(summarise(base + duration), 60.0, 2, ran=5)
    row = next(line for line in text.splitlines() if line.startswith(f"| `{nm}` | 67 %"))
    assert "(2/3;" in row and "0 % (0/1;" in row and "| – |" in row
    assert "for the 5 cases of this run" in text


def test_same_verdicts_flags_a_changed_named_list_and_counts_unmatched(tmp_path, capsys):
    """experiments/same_verdicts.py: equal named sets (in any order) pass; a changed one fails
    with exit 1 and is printed; a case only in the new run is counted, not compared."""
    import json

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


def test_lagged_privileged_pays_for_knowing_the_noise_one_window_late(capsys):
    """On manoeuvre_heavy the privileged policy that sets R from the window just flown is worse
    than the one that knows the coming window (the flex noise moves within a second), and the
    table has a row per decision window."""
    lagged = experiment("lagged_privileged")["main"]  # returns its rows, which the test reads
    rows = lagged(["--windows", "10", "--episodes", "2"])
    assert [r["window"] for r in rows] == [10]
    assert rows[0]["late"] > rows[0]["privileged"]
    assert "| 10 |" in capsys.readouterr().out


def test_lagged_privileged_with_a_floor_on_r_keeps_a_late_burst_out(capsys):
    """On noise_bursts the late policy lets the first window of each burst in at a small R;
    held at R ≥ 10² R(0) it loses far less (the teacher the general policy's cloning follows)."""
    lagged = experiment("lagged_privileged")["main"]
    rows = lagged(
        ["--scenario", "noise_bursts", "--windows", "10", "--episodes", "2", "--floors", "2"]
    )
    assert rows[0]["late_floored"][2.0] < rows[0]["late"] - 0.5
    out = capsys.readouterr().out
    assert "late, R ≥ 10^2 R(0)" in out and out.count("|---") == 5
    with pytest.raises(SystemExit):
        lagged(["--floors", "high"])
    assert "--floors 'high'" in capsys.readouterr().err
