"""The learners' benchmark steps (``agents.comparison.pipeline``) on hand-made runs whose answers
are known: which runs count as finished, the data files in the format the statistics read back
(``agents.comparison.statistics.flight_table``), the choice of the policy to ship and shipping
it. The steps that train and fly run end to end, test-sized, in ``tests/test_experiments.py``
(``experiments/compare_learners.py --quick``, marked slow)."""

from __future__ import annotations

import csv
import io
import json
from pathlib import Path

import numpy as np
import pytest

from aeromag_env.errors import AeromagError
from aeromag_env.parallel import SerialRunner
from agents.comparison import pipeline
from agents.comparison.statistics import flight_table
from agents.policies import DEFAULT_PPO, GENERAL_PPO
from agents.policies.policy_file import read_policy
from tests._helpers import assert_one_line_error


def _summary(minutes: float, scores: list[float], eval_episodes: int = 16) -> dict:
    """A ``training.json`` summary with a curve of validation points, one per score."""
    curve = [
        {
            "timesteps": 1000 * (k + 1),
            "seconds": 10.0 * (k + 1) + 0.123,
            "validation_rmse_nt": 2.0 + score,
            "validation_score": score,
            "validation_rmse_by_scenario": {"paper": 1.5 + score, "nominal": 2.5 + score},
        }
        for k, score in enumerate(scores)
    ]
    return {
        "timesteps": 1000 * len(scores),
        "train_seconds_this_run": 60.0 * minutes,
        "best_validation_score": min(scores),
        "hyperparams": {"eval_episodes": eval_episodes, "timesteps": 1000 * len(scores)},
        "curve": curve,
    }


def _run(runs: Path, learner: str, seed: int, summary: dict | None, policy: bool = True) -> Path:
    folder = pipeline.run_folder(runs, learner, seed)
    folder.mkdir(parents=True)
    if summary is not None:
        (folder / "training.json").write_text(json.dumps(summary))
    if policy:
        (folder / "policy.npz").write_bytes(GENERAL_PPO.read_bytes())
    return folder


def test_finished_runs_are_those_with_a_policy_and_a_summary_in_learner_order(tmp_path):
    _run(tmp_path, "sac", 1, _summary(1.0, [0.9]))
    _run(tmp_path, "sac", 0, _summary(1.0, [0.8]))
    _run(tmp_path, "cmaes", 0, None)  # still training: no training.json
    _run(tmp_path, "tqc", 0, _summary(1.0, [0.7]), policy=False)
    _run(tmp_path, "ppo", 3, _summary(1.0, [0.7]))
    (tmp_path / "data").mkdir()  # the data folder beside the runs is not a learner
    found = pipeline.finished_runs(tmp_path)
    assert list(found) == ["ppo/3", "sac/0", "sac/1"]
    assert found["sac/1"] == tmp_path / "sac" / "seed_1" / "policy.npz"


def test_flights_csv_is_what_the_statistics_read_back():
    """Every policy's RMSE per scenario and flight, written and read by
    :func:`~agents.comparison.statistics.flight_table`: the same numbers, bit for bit."""
    rng = np.random.default_rng(0)
    seeds, scenarios = [200_000, 200_001, 200_002], ("paper", "noise_bursts")
    names = {"sac/0": "ppo:a.npz", "sac/1": "ppo:b.npz", "cmaes/0": "ppo:c.npz"}
    policies = [*pipeline.REFERENCES, *names.values()]
    results = {
        s: {"policies": {p: {"rmse_nt": list(rng.uniform(0.5, 3.0, 3))} for p in policies}}
        for s in scenarios
    }
    table = flight_table(csv.DictReader(io.StringIO(pipeline.flights_csv(results, names, seeds))))
    assert table.scenarios == scenarios and table.seeds == {"sac": (0, 1), "cmaes": (0,)}
    np.testing.assert_array_equal(table.flights, [seeds, seeds])
    for k, s in enumerate(scenarios):
        ref = results[s]["policies"]["privileged"]["rmse_nt"]
        assert list(table.references["privileged"][k]) == ref
        assert list(table.learners["sac"][1, k]) == results[s]["policies"]["ppo:b.npz"]["rmse_nt"]


def test_curves_give_every_validation_point_and_each_runs_record(tmp_path):
    _run(tmp_path, "sac", 0, _summary(12.5, [0.9, 0.6, 0.7], eval_episodes=16))
    text, records = pipeline.curves(pipeline.finished_runs(tmp_path))
    rows = list(csv.DictReader(io.StringIO(text)))
    assert tuple(rows[0]) == pipeline.CURVE_COLUMNS
    assert len(rows) == 3 * 2  # three points, two scenarios each
    per = 16 // 7  # the validation flights split over the suite's scenarios
    assert {r["flights"] for r in rows} == {str(per)}
    assert rows[2] == {
        "learner": "sac",
        "seed": "0",
        "timesteps": "2000",
        "seconds": "20.12",
        "train_seconds": "20.12",
        "scenario": "paper",
        "flights": str(per),
        "validation_rmse_nt": repr(1.5 + 0.6),
    }
    (record,) = records
    assert (record["minutes"], record["kept_timesteps"], record["seed"]) == (12.5, 2000, 0)
    assert record["validation_flights"] == per and record["best_validation_score"] == 0.6


def test_the_learner_with_the_lowest_mean_wins_and_its_best_seed_is_chosen():
    """sac has the single best seed but the worse mean; tqc wins, with its seed 2."""
    scores = {"sac/0": 0.5, "sac/1": 1.9, "tqc/0": 0.9, "tqc/2": 0.7, "tqc/4": 0.8}
    means, chosen = pipeline.choose(scores)
    assert means == pytest.approx({"sac": 1.2, "tqc": 0.8})
    assert chosen == {"learner": "tqc", "seed": 2}


def test_ship_writes_the_chosen_policy_once_and_refuses_other_settings(tmp_path):
    runs, data, target = tmp_path / "runs", tmp_path / "data", tmp_path / "shipped.npz"
    _run(runs, "sac", 3, _summary(1.0, [0.5]))
    data.mkdir()
    with pytest.raises(AeromagError) as e:
        pipeline.ship(runs, data, target)
    assert_one_line_error(e, f"no {data / pipeline.SELECTION} (choose the policy first")
    (data / pipeline.SELECTION).write_text(json.dumps({"chosen": {"learner": "sac", "seed": 3}}))
    assert pipeline.ship(runs, data, target) == f"wrote {target}: sac seed 3"
    arrays, meta = read_policy(target)
    shipped, _ = read_policy(GENERAL_PPO)
    assert meta["env_kwargs"] == {"preset": "general"} and meta["learner"] == "sac"
    assert all(np.array_equal(arrays[k], shipped[k]) for k in shipped)
    assert pipeline.ship(runs, data, target) == f"{target} already holds sac seed 3's policy"
    other = pipeline.run_folder(runs, "sac", 3) / "policy.npz"
    other.write_bytes(DEFAULT_PPO.read_bytes())  # the nonstationary policy's settings
    with pytest.raises(AeromagError) as e:
        pipeline.ship(runs, data, tmp_path / "other.npz")
    assert_one_line_error(e, "not trained with the general preset's settings")
    assert not (tmp_path / "other.npz").exists()


def test_a_finished_run_is_not_trained_again(tmp_path):
    folder = _run(tmp_path, "cmaes", 0, _summary(3.0, [0.5]))
    outcomes = pipeline.train(["cmaes"], [0], tmp_path, SerialRunner())
    assert [o.ok for o in outcomes] == [True]
    assert outcomes[0].value["trained_now"] is False
    assert outcomes[0].value["train_seconds_this_run"] == 180.0
    assert (folder / "policy.npz").read_bytes() == GENERAL_PPO.read_bytes()


def test_the_steps_refuse_unknown_learners_and_empty_runs_in_one_line(tmp_path):
    with pytest.raises(AeromagError) as e:
        pipeline.train(["sac", "dqn"], [0], tmp_path, SerialRunner())
    assert_one_line_error(e, "dqn", "valid: ppo, recurrent_ppo, sac, tqc, cmaes")
    for step in (
        lambda: pipeline.evaluate(tmp_path, tmp_path / "d", SerialRunner(), episodes=2, command=""),
        lambda: pipeline.select(tmp_path, tmp_path / "d", SerialRunner(), flights=1, command=""),
    ):
        with pytest.raises(AeromagError) as e:
            step()
        assert_one_line_error(e, f"no finished runs under {tmp_path}")
    assert not (tmp_path / "d").exists()
