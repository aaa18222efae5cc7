"""The benchmark plumbing (never speed: that is for ``aeromag bench``)."""

import numpy as np

from aeromag_env.bench import _rows, peak_rss_mb
from aeromag_env.bench_filters import bench_filters
from aeromag_env.compensate import earth_model


def test_filter_figures_are_positive_rates(nominal_box):
    t_b, td = earth_model(nominal_box)
    y = nominal_box.vector("flux_a") - t_b
    figures = bench_filters(y[:200], t_b[:200], td[:200], repeats=1)
    assert set(figures) == {"filter_compiled_samples_per_s", "filter_batched_samples_per_s",
                            "filter_numpy_samples_per_s", "filterpy_samples_per_s"}  # fmt: skip
    assert all(v is not None and v > 0 for v in figures.values())


def test_table_rows_give_ratios_and_targets_and_tolerate_missing_figures():
    figures = {
        "simulate_s_per_flight_hour": 0.05, "simulate_direct_igrf_s_per_flight_hour": 1.0,
        "filter_compiled_samples_per_s": 1.6e6, "filter_batched_samples_per_s": 3e6,
        "filter_numpy_samples_per_s": 8e3, "filterpy_samples_per_s": None,
        "env_single_steps_per_s": 5e4, "env_numpy_reference_steps_per_s": 800.0,
        "env_batched_steps_per_s": 2e5, "env_reset_s": 0.03,
        **{f"{prefix}_{variant}_{what}": value
           for prefix in ("ppo", "ppo64")
           for variant, rate in (("batched", 6e3), ("batched_no_prefetch", 5.5e3),
                                 ("dummyvec", 5e3))
           for what, value in (("steps_per_s", rate), ("env_time_share", 0.4))},
        "ppo_n_envs": 8, "ppo64_n_envs": 64,
        "discover_s_per_flight_hour": None,
        "compensate_10h_peak_mb": 600.0, "compensate_baseline_mb": 40.0,
    }  # fmt: skip
    rows = {r[0]: r for r in _rows(figures)}
    assert rows["filter, compiled, 1 flight"][2:] == ("n/a", "≥ 30× filterpy", None)
    assert rows["env steps, 64 envs batched, K = 10"][2] == "4.0× 1 env"
    assert rows["PPO learn, batched + prefetch, 8 envs"][2:] == (
        "1.20× DummyVecEnv (env: 40% of the time)", "≥ 1.5× DummyVecEnv", False)  # fmt: skip
    assert rows["PPO learn, DummyVecEnv, 64 envs"][2:] == (
        "1.00× DummyVecEnv (env: 40% of the time)", "", None)  # fmt: skip
    assert rows["discover 1 flight-hour"][1:3] == ("n/a", "n/a")
    assert rows["compensate 10-hour flight, peak RSS"][4] is True
    assert np.isfinite(peak_rss_mb()) and peak_rss_mb() > 0
