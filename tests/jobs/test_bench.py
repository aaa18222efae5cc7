"""The benchmark plumbing (never speed: that is for ``aeromag bench``)."""

import copy
import functools
import json

import numpy as np
import pytest

from aeromag_env.compensation.compensate import earth_model
from aeromag_env.compensation.kalman_batch import BatchFilterState
from aeromag_env.compensation.model import FilterConfig
from aeromag_env.jobs.bench import BenchRequest, _report
from aeromag_env.jobs.bench.filters import bench_filters
from aeromag_env.jobs.bench.table import rows as table_rows
from aeromag_env.jobs.bench.workflows import peak_rss_mb
from tests._flights import simulated
from tests._helpers import assert_one_line_error, experiment


@pytest.mark.slow
def test_filter_figures_are_positive_rates(nominal_box):
    t_b, td = earth_model(nominal_box)
    y = nominal_box.vector("flux_a") - t_b
    figures = bench_filters(y[:200], t_b[:200], td[:200], repeats=1)
    assert set(figures) == {
        "filter_compiled_samples_per_s",
        "filter_batched_samples_per_s",
        "filter_numpy_samples_per_s",
        "filterpy_samples_per_s",
    }
    assert all(v is not None and v > 0 for v in figures.values())


#: A bench.json's figures, made up: the table's arithmetic, not speed.
FIGURES = {
    "simulate_s_per_flight_hour": 0.05,
    "simulate_direct_igrf_s_per_flight_hour": 1.0,
    "filter_compiled_samples_per_s": 1.6e6,
    "filter_batched_samples_per_s": 3e6,
    "filter_numpy_samples_per_s": 8e3,
    "filterpy_samples_per_s": 5e4,
    "env_single_steps_per_s": 5e4,
    "env_numpy_reference_steps_per_s": 800.0,
    "env_batched_steps_per_s": 2e5,
    "env_reset_s": 0.03,
    **{
        f"{prefix}_{variant}_{what}": value
        for prefix in ("ppo", "ppo64")
        for variant, rate in (("batched", 6e3), ("batched_no_prefetch", 5.5e3), ("dummyvec", 5e3))
        for what, value in (("steps_per_s", rate), ("env_time_share", 0.4))
    },
    "ppo_n_envs": 8,
    "ppo64_n_envs": 64,
    "discover_s_per_flight_hour": 5.0,
    "compensate_10h_peak_mb": 600.0,
    "compensate_baseline_mb": 40.0,
}


def test_table_rows_give_ratios_and_targets_and_tolerate_missing_figures():
    figures = {
        **FIGURES,
        "filterpy_samples_per_s": None,
        "discover_s_per_flight_hour": None,
        "ppo64_free_steps_per_s": 1e4,
        "ppo64_free_env_time_share": 0.0,
        "ppo64_batched_ratio_min": 1.1,
        "ppo64_batched_ratio_max": 1.3,
    }
    rows = {r[0]: r for r in table_rows(figures)}
    assert rows["filter, compiled, 1 flight"][2:] == ("n/a", "≥ 30× filterpy", None)
    assert rows["env steps, 64 envs batched, K = 10"][2] == "4.0× 1 env"
    assert rows["PPO learn, batched + prefetch, 8 envs"][2:] == (
        "1.20× DummyVecEnv (env: 40% of the time)",
        "≥ 1.5× DummyVecEnv",
        False,
    )
    assert rows["PPO learn, DummyVecEnv, 64 envs"][2:] == (
        "1.00× DummyVecEnv (env: 40% of the time)",
        "",
        None,
    )
    assert rows["PPO learn, batched + prefetch, 64 envs"][2] == (
        "1.20× DummyVecEnv (repeats 1.10–1.30; env: 40% of the time)"
    )
    assert rows["PPO learn, zero-cost env, 64 envs"][2] == (
        "2.00× DummyVecEnv (PPO alone: the most any env allows)"
    )
    assert "PPO learn, zero-cost env, 8 envs" not in rows  # older bench.json: not measured
    assert rows["discover 1 flight-hour"][1:] == ("n/a", "n/a", "≤ 5 s", None)
    assert {r[0]: r for r in table_rows(FIGURES)}["discover 1 flight-hour"][1:] == (
        "5.00 s",
        "720× real time",
        "≤ 5 s",
        True,
    )
    assert rows["compensate 10-hour flight, peak RSS"][4] is True
    assert np.isfinite(peak_rss_mb()) and peak_rss_mb() > 0


def test_each_filter_method_has_a_cost_row_against_the_kf(nominal_box):
    """``method_costs`` times every method of ``COST_METHODS`` side by side (the KF's ratio is 1
    by construction); the table gives each its µs per sample and ratio; an older bench.json
    without the figures has no such rows."""
    from aeromag_env.compensation.cost import COST_METHODS
    from aeromag_env.jobs.bench.filters import method_costs

    t_b, td = earth_model(nominal_box)
    y = nominal_box.vector("flux_a") - t_b
    figures = method_costs(y[:100], t_b[:100], td[:100], repeats=1)
    keys = [m.replace("-", "_") for m in COST_METHODS]
    assert set(figures) == {f"filter_cost_{w}_{k}" for k in keys for w in ("s_per_sample", "ratio")}
    assert figures["filter_cost_ratio_kf"] == 1.0
    assert all(v > 0 for v in figures.values())
    made_up = {**FIGURES, **figures, "filter_cost_s_per_sample_imm": 4e-6}
    made_up["filter_cost_ratio_imm"] = 5.0
    rows = {r[0]: r for r in table_rows(made_up)}
    assert rows["filter cost per sample, imm"][1:] == ("4.00 µs", "5.00× kf", "", None)
    assert len([r for r in rows if r.startswith("filter cost per sample, ")]) == len(keys)
    assert not any(r[0].startswith("filter cost") for r in table_rows(FIGURES))


#: The environments-inside-PPO figures, made up: 23.4 µs per step against a 7.8 µs filter at 8
#: environments, 10.5 against 7.0 at 64; the env's share 12 % at both.
TARGET_FIGURES = {
    **{
        f"{prefix}_env_share{end}": value
        for prefix in ("ppo", "ppo64")
        for end, value in (("", 0.12), ("_min", 0.1), ("_max", 0.17))
    },
    **{
        f"{prefix}_{name}": value
        for prefix, env, kernel in (("ppo", 23.4, 7.8), ("ppo64", 10.5, 7.0))
        for name, value in (
            ("decision_window", 10),
            ("env_us_per_step", env),
            ("filter_us_per_step", kernel),
            ("env_to_filter_ratio", env / kernel),
            ("env_to_filter_ratio_min", 0.9 * env / kernel),
            ("env_to_filter_ratio_max", 1.1 * env / kernel),
        )
    },
}


def test_env_share_rows_carry_the_target_at_64_envs_only():
    rows = {r[0]: r for r in table_rows({**FIGURES, **TARGET_FIGURES})}
    assert rows["PPO learn, the env's share, 64 envs"][1:] == (
        "12.0%",
        "1 − batched/zero-cost, paired repeats 10.0–17.0%",
        "≤ 20%",
        True,
    )
    assert rows["PPO learn, the env's share, 8 envs"][3:] == ("", None)
    slow = {**FIGURES, **TARGET_FIGURES, "ppo64_env_share": 0.21}
    assert {r[0]: r for r in table_rows(slow)}["PPO learn, the env's share, 64 envs"][4] is False
    assert "PPO learn, the env's share, 8 envs" not in {r[0] for r in table_rows(FIGURES)}


def test_filter_rows_give_the_ratio_to_the_bare_filter_with_its_target_at_8_envs():
    rows = {r[0]: r for r in table_rows({**FIGURES, **TARGET_FIGURES})}
    assert rows["PPO learn, the envs per step vs the bare filter, 8 envs"][1:] == (
        "23.4 µs per env step",
        "3.00× the filter's 7.8 µs for K = 10 samples (repeats 2.70–3.30)",
        "≤ 1.5× the filter",
        False,
    )
    assert rows["PPO learn, the envs per step vs the bare filter, 64 envs"][1:] == (
        "10.5 µs per env step",
        "1.50× the filter's 7.0 µs for K = 10 samples (repeats 1.35–1.65)",
        "",
        None,
    )
    fast = {**FIGURES, **TARGET_FIGURES, "ppo_env_to_filter_ratio": 1.5}
    met = {r[0]: r for r in table_rows(fast)}[
        "PPO learn, the envs per step vs the bare filter, 8 envs"
    ]
    assert met[4] is True
    assert not any("bare filter" in r[0] for r in table_rows(FIGURES))  # an older bench.json


def test_report_writes_and_prints_the_two_targets(tmp_path):
    figures = {**FIGURES, **TARGET_FIGURES}
    request = BenchRequest(out=tmp_path, quick=True)
    result = _report(request, figures, table_rows(figures), None)
    written = json.loads((tmp_path / "bench.json").read_text())
    assert written == json.loads(json.dumps(result.report))
    assert written["figures"]["ppo_env_to_filter_ratio"] == pytest.approx(23.4 / 7.8, rel=1e-15)
    targets = {r["benchmark"]: r["target"] for r in written["rows"]}
    assert targets["PPO learn, the envs per step vs the bare filter, 8 envs"] == "≤ 1.5× the filter"
    assert targets["PPO learn, the env's share, 64 envs"] == "≤ 20%"
    printed = result.table.splitlines()

    def line(name):
        (found,) = [x for x in printed if x.startswith(f"{name} ")]
        return found

    ratio = line("PPO learn, the envs per step vs the bare filter, 8 envs")
    assert "23.4 µs per env step" in ratio and "3.00× the filter's 7.8 µs" in ratio
    assert ratio.endswith("≤ 1.5× the filter (NOT met)")
    assert line("PPO learn, the env's share, 64 envs").endswith("≤ 20% (met)")
    assert line("PPO learn, the env's share, 8 envs").rstrip().endswith("10.0–17.0%")  # no target


def test_zero_cost_env_ends_episodes_as_sb3_expects():
    from gymnasium import spaces

    from aeromag_env.jobs.bench.envs import free_vec_env

    obs_space = spaces.Box(-1.0, 1.0, (4,), np.float32)
    env = free_vec_env(2, obs_space, spaces.Box(-1.0, 1.0, (3,), np.float32), episode_steps=3)
    first = env.reset()
    assert first.shape == (2, 4) and obs_space.contains(first[0])
    ends = []
    for _ in range(6):
        env.step_async(np.zeros((2, 3), np.float32))
        _, _, dones, infos = env.step_wait()
        ends.append(bool(dones.all()))
        truncated = infos[0]["TimeLimit.truncated"]
        assert dones.all() == ("terminal_observation" in infos[1]) == truncated
    assert ends == [False, False, True, False, False, True]


def test_bench_table_joins_runs_and_counts_met_targets(tmp_path):
    script = experiment("bench_table")
    join_cells, load_runs, table = (script[n] for n in ("join_cells", "load_runs", "table"))

    assert join_cells(["1.2× filterpy", "1.35× filterpy"]) == "1.2 / 1.35× filterpy"
    assert join_cells(["1,000 /s", "1,000 /s"]) == "1,000 /s"
    ranges = ["1.2× a (repeats 1.1–1.3; env 5%)", "1.3× a (repeats 1.2–1.4; env 5%)"]
    assert join_cells(ranges) == "1.2 / 1.3× a (repeats 1.1–1.3 / 1.2–1.4; env 5%)"
    shares = ["share 35.7% (repeats -5.5–59.2%)", "share 31.7% (repeats 31.5–57.7%)"]
    assert join_cells(shares) == "share 35.7 / 31.7% (repeats -5.5–59.2 / 31.5–57.7%)"
    split = [
        "environments 39; policy forward 5; rest -2 µs",
        "environments 39; policy forward 3; rest 4 µs",
    ]
    assert join_cells(split) == "environments 39; policy forward 5 / 3; rest -2 / 4 µs"
    cells = ["1.2× a", "1.3× b"]
    assert join_cells(cells) == "<br>".join(cells)  # they differ in words
    slow = {**FIGURES, "env_single_steps_per_s": 1.5e4}
    paths = []
    for i, f in enumerate((FIGURES, slow)):
        paths.append(tmp_path / f"{i}.json")
        paths[-1].write_text(json.dumps({"figures": f}))
    rows = {line.split(" | ")[0]: line for line in table(load_runs(paths)).splitlines()}
    assert rows["| env steps, 1 env, K = 10"].endswith("≥ 20 000 /s: met in 1 of 2 |")
    assert "| 50,000 / 15,000 /s |" in rows["| env steps, 1 env, K = 10"]
    (tmp_path / "bad.json").write_text("{}")
    with pytest.raises(SystemExit, match=r"not an aeromag bench\.json"):
        load_runs([tmp_path / "bad.json"])


@pytest.mark.slow  # two fresh processes running discover (tests/jobs/test_bench_discover.py)
def test_bench_only_discover_measures_the_workflow_alone(tmp_path, capsys):
    from aeromag_env.cli.main import main

    assert main(["bench", "--only", "discover", "--quick", "--out", str(tmp_path)]) == 0
    result = json.loads((tmp_path / "bench.json").read_text())
    assert {k for k in result["figures"] if not k.startswith("discover_cli_")} == {
        "discover_s_per_flight_hour"
    }
    assert result["figures"]["discover_cli_0.5h_peak_mb"] > 0  # the fresh process's run too
    assert result["figures"]["discover_s_per_flight_hour"] > 0
    assert [r["benchmark"] for r in result["rows"]] == [
        "discover 1 flight-hour",
        "aeromag discover, fresh process, 0.5 flight-hour file",
        "aeromag discover, 0.5 flight-hour file, peak RSS",
    ]
    assert result["rows"][0]["target"] == "≤ 5 s"
    assert "discover 1 flight-hour" in capsys.readouterr().out


def test_extra_time_row_splits_the_batched_runs_extra_time_by_part():
    per_step = {
        "env": (40.0, 2.0),
        "forward": (60.0, 50.0),
        "update": (100.0, 101.0),
        "rest": (30.0, 27.0),
    }
    rates = {
        "ppo_free_steps_per_s": 1e6 / 180.0,
        "ppo_batched_steps_per_s": 1e6 / 230.0,
        "ppo_free_env_time_share": 0.01,
    }
    figures = {
        **FIGURES,
        **rates,
        **{
            f"ppo_{variant}_{part}_us_per_step": values[i]
            for part, values in per_step.items()
            for i, variant in enumerate(("batched", "free"))
        },
    }
    rows = {r[0]: r for r in table_rows(figures)}
    assert rows["PPO learn, batched + prefetch beyond zero-cost, 8 envs"][1:] == (
        "50 µs per env step",
        "environments 38; policy forward 10; updates -1; rest 3 µs more",
        "",
        None,
    )
    assert "PPO learn, batched + prefetch beyond zero-cost, 64 envs" not in rows  # not measured


class _FakeModel:
    """Stands in for a PPO model: logs its ``learn`` calls, adds to its running part totals."""

    def __init__(self, name, log, totals):
        self.name, self.log, self.totals = name, log, totals

    def learn(self, steps, reset_num_timesteps=True):
        assert reset_num_timesteps is False
        self.log.append((self.name, steps))
        self.totals["env"][0] += 1.0
        self.totals["forward"][0] += 0.5


def test_interleaved_takes_turns_a_rollout_at_a_time_and_restarts_the_totals_each_repeat():
    from aeromag_env.jobs.bench.envs import PARTS, _interleaved

    log: list = []
    running = {name: {part: [7.0] for part in PARTS} for name in "ab"}
    models = {name: _FakeModel(name, log, running[name]) for name in "ab"}
    kernel = [7.0]
    running["c"] = {"kernel": kernel}  # a run with parts of its own, as the bare filter

    def c(steps):
        log.append(("c", steps))
        kernel[0] += 0.25

    runs = {
        name: functools.partial(m.learn, reset_num_timesteps=False) for name, m in models.items()
    }
    seconds, parts = _interleaved(runs | {"c": c}, running, timesteps=250, repeats=2, rollout=100)
    turns = [log[i : i + 3] for i in range(0, len(log), 3)]
    assert [[name for name, _ in turn] for turn in turns[:3]] == [
        list("abc"),
        list("bca"),
        list("cab"),
    ]
    assert [steps for _, steps in turns[2]] == [50, 50, 50]  # the last, partial rollout
    assert sum(steps for name, steps in log if name == "a") == 2 * 250
    assert parts["b"]["env"] == [3.0, 3.0] and parts["b"]["forward"] == [1.5, 1.5]
    assert parts["b"]["update"] == [0.0, 0.0]
    assert parts["c"] == {"kernel": [0.75, 0.75]}
    assert all(len(s) == 2 and all(x >= 0 for x in s) for s in seconds.values())


def test_filter_figures_are_medians_per_env_step_and_their_quotient():
    from aeromag_env.jobs.bench.envs import filter_figures

    parts = {"batched": {"env": [0.3, 0.2, 0.6]}, "filter": {"kernel": [0.1, 0.05, 0.1]}}
    figures = filter_figures("ppo64", parts, timesteps=10_000, window=10)
    assert figures == pytest.approx(
        {
            "ppo64_decision_window": 10,
            "ppo64_env_us_per_step": 30.0,  # 0.3 s / 10 000 steps
            "ppo64_filter_us_per_step": 10.0,
            "ppo64_env_to_filter_ratio": 3.0,
            "ppo64_env_to_filter_ratio_min": 3.0,
            "ppo64_env_to_filter_ratio_max": 6.0,
        },
        rel=1e-12,  # float rounding of the divisions
    )


def test_filter_figures_against_the_filter_inside_ppo_pair_each_repeat():
    from aeromag_env.jobs.bench.envs import IN_PPO, filter_figures

    parts = {
        "batched": {"env": [0.3, 0.2, 0.6]},
        "filter": {"kernel": [0.1, 0.05, 0.1]},
        IN_PPO: {"kernel": [0.2, 0.1, 0.4]},
    }
    figures = filter_figures("ppo", parts, timesteps=10_000, window=10)
    assert figures["ppo_env_to_filter_ratio"] == pytest.approx(3.0, rel=1e-12)  # unchanged
    assert figures["ppo_filter_in_ppo_us_per_step"] == pytest.approx(20.0, rel=1e-12)
    assert figures["ppo_env_to_filter_in_ppo_ratio"] == pytest.approx(1.5, rel=1e-12)
    assert figures["ppo_env_to_filter_in_ppo_ratio_min"] == pytest.approx(1.5, rel=1e-12)
    assert figures["ppo_env_to_filter_in_ppo_ratio_max"] == pytest.approx(2.0, rel=1e-12)


def test_filter_in_ppo_row_is_a_diagnostic_without_a_target():
    inside = {
        "ppo_filter_in_ppo_us_per_step": 18.0,
        "ppo_env_to_filter_in_ppo_ratio": 1.3,
        "ppo_env_to_filter_in_ppo_ratio_min": 1.2,
        "ppo_env_to_filter_in_ppo_ratio_max": 1.4,
    }
    rows = {r[0]: r for r in table_rows({**FIGURES, **TARGET_FIGURES, **inside})}
    assert rows["PPO learn, the envs per step vs the filter inside PPO, 8 envs"][1:] == (
        "23.4 µs per env step",
        "1.30× the filter's 18.0 µs stepped inside PPO as the envs are (repeats 1.20–1.40)",
        "",
        None,
    )
    # the target's row still compares with the filter run back to back
    assert rows["PPO learn, the envs per step vs the bare filter, 8 envs"][4] is False
    assert not any("inside PPO" in r[0] for r in table_rows({**FIGURES, **TARGET_FIGURES}))


def test_zero_cost_env_does_its_work_once_per_step():
    from gymnasium import spaces

    from aeromag_env.jobs.bench.envs import free_vec_env

    calls = []
    box = spaces.Box(-1.0, 1.0, (3,), np.float32)
    env = free_vec_env(2, box, box, episode_steps=3, work=lambda: calls.append(1))
    env.reset()
    for _ in range(4):
        env.step_async(np.zeros((2, 3), np.float32))
        env.step_wait()
    assert len(calls) == 4


def test_bare_filter_advances_a_window_per_step_and_restarts_ended_flights():
    from aeromag_env.jobs.bench.envs import BareFilter

    f = simulated("paper", 1)
    t_b, td = earth_model(f, "backward")
    y = f.vector("flux_a") - t_b
    cuts = ((0, 95), (200, 330))  # 95 and 130 samples: the first ends inside its tenth window
    flights = [(y[a:b], t_b[a:b], td[a:b]) for a, b in cuts]
    start = BatchFilterState.from_flights(FilterConfig(r_std_nt=20.0), *zip(*flights, strict=True))
    bare = BareFilter(start, window=10)
    bare(2 * 9 + 1)  # nine windows of two environments (a step short of a tenth)
    assert list(bare.filters.k) == [90, 90] and list(start.k) == [0, 0]
    reference = copy.deepcopy(start)
    reference.advance(90)
    np.testing.assert_array_equal(bare.filters.est, reference.est)  # the same kernel: bitwise
    reference_at_90 = copy.deepcopy(reference)
    bare(2)  # flight 0 ends at 95 and starts over; flight 1 goes on
    assert list(bare.filters.k) == [0, 100]
    np.testing.assert_array_equal(bare.filters.est[0], start.est[0])
    np.testing.assert_array_equal(bare.filters.z[0], start.z[0])
    reference.advance(100)
    np.testing.assert_array_equal(bare.filters.est[1], reference.est[1])
    assert bare.seconds[0] > 0.0
    again = bare.fresh()  # the same flights from their start, its own clock
    assert list(again.filters.k) == [0, 0] and again.seconds == [0.0]
    again(2 * 9)
    np.testing.assert_array_equal(again.filters.est, reference_at_90.est)


@pytest.mark.slow
def test_bench_ppo_reports_the_environments_against_the_bare_filter():
    from aeromag_env.jobs.bench.envs import bench_ppo

    figures = bench_ppo(64, 2, n_envs=2, n_steps=16, batch_size=16)
    ratio = figures["ppo_env_us_per_step"] / figures["ppo_filter_us_per_step"]
    assert figures["ppo_env_to_filter_ratio"] == pytest.approx(ratio, rel=1e-15)
    assert figures["ppo_env_us_per_step"] == figures["ppo_batched_env_us_per_step"]
    assert figures["ppo_env_to_filter_ratio_min"] <= figures["ppo_env_to_filter_ratio_max"]
    assert figures["ppo_decision_window"] == 10 and figures["ppo_filter_us_per_step"] > 0
    inside = figures["ppo_env_us_per_step"] / figures["ppo_filter_in_ppo_us_per_step"]
    assert figures["ppo_env_to_filter_in_ppo_ratio"] == pytest.approx(inside, rel=1e-15)


def test_bench_ppo_wants_whole_steps_of_every_environment():
    from aeromag_env.jobs.bench.envs import bench_ppo

    with pytest.raises(ValueError) as error:
        bench_ppo(63, 1, n_envs=2)
    assert_one_line_error(error, "timesteps", "multiple of n_envs (2)", "got 63")


def test_zero_cost_env_episodes_are_as_long_in_steps_as_the_flights():
    from aeromag_env.jobs.bench.envs import _stand_ins
    from agents.training import ppo

    hp = ppo.load_hyperparams("nonstationary").with_values(n_envs=2, prefetch=False)
    venv = ppo.make_training_env("nonstationary", hp, seed=0)
    venv.reset()
    batched = venv.venv.venv
    samples, window = int(batched.episode_lengths.max()), batched.config.decision_window
    env = _stand_ins(venv)[0]()
    env.reset()
    steps, done = 0, False
    while not done:
        env.step_async(np.zeros((2, *env.action_space.shape), np.float32))
        done = bool(env.step_wait()[2].all())
        steps += 1
    assert steps == -(-samples // window) and steps < samples


@pytest.mark.slow
def test_bench_only_ppo_measures_the_speed_targets_figures_alone(tmp_path, capsys):
    from aeromag_env.cli.main import main

    assert main(["bench", "--only", "ppo", "--quick", "--out", str(tmp_path)]) == 0
    result = json.loads((tmp_path / "bench.json").read_text())
    figures = result["figures"]
    assert all(k.startswith("ppo") for k in figures) and "ppo_env_to_filter_ratio" in figures
    ratio = figures["ppo_env_us_per_step"] / figures["ppo_filter_us_per_step"]
    assert figures["ppo_env_to_filter_ratio"] == pytest.approx(ratio)
    assert all(r["benchmark"].startswith("PPO") for r in result["rows"])
    assert "≤ 1.5× the filter" in capsys.readouterr().out


def test_bench_only_stream_measures_latency_and_memory_per_model(tmp_path, capsys):
    """``--only stream``: per model, the latency (wall and processor time) of every sample the
    stream answered, the memory once per simulated hour, and the rows with their targets."""
    from aeromag_env.jobs.bench.stream import bench_stream, stream_rows

    figures = bench_stream(hours=0.02)  # 720 samples of each model
    for method, wait in (("tl", 2), ("kf", 1)):
        assert figures[f"stream_{method}_samples"] == 720
        assert figures[f"stream_{method}_answered"] == 720  # a clean flight: every sample
        lat, cpu = figures[f"stream_{method}_latency_us"], figures[f"stream_{method}_cpu_us"]
        assert 0 < lat["median"] <= lat["p99"] <= lat["max"]
        assert cpu["median"] > 0 and figures[f"stream_{method}_lookahead_samples"] == wait
        assert len(figures[f"stream_{method}_rss_mib"]) == 2  # the first hour and the end
    rows = stream_rows(figures)
    assert [r[0] for r in rows] == [
        "stream tl, latency per sample",
        "stream tl, memory over 0.02 h",
        "stream kf, latency per sample",
        "stream kf, memory over 0.02 h",
    ]
    assert rows[0][3] == "p99 < 100 000 µs" and rows[1][3] == "flat (±1 MiB)"
