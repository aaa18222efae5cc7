"""A search rerun with the request its ``tune.json`` records is not run again
(:func:`aeromag_env.jobs.tune.finished_search`); any other request is run."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

from aeromag_env.jobs.tune import TuneRequest, finished_search
from agents.search.space import SPACE, recorded_path
from agents.training import ppo


def _record(req: TuneRequest, samples: int) -> dict:
    """What a finished PPO search of ``req`` with ``samples`` trials writes to ``tune.json``."""
    return {
        "scenario": "nonstationary",
        "samples": samples,
        "timesteps": 1024,
        "seed": req.seed,
        "quick": req.quick,
        "space_file": recorded_path(SPACE),
        "hyperparams": recorded_path(ppo.HYPERPARAMS),
        "trials": [{"trial": k} for k in range(samples)],
    }


def test_the_recorded_request_is_finished_and_any_other_is_not(tmp_path: Path) -> None:
    req = TuneRequest(out=tmp_path, samples=3, timesteps=1024)
    record = _record(req, samples=3)
    (tmp_path / "tune.json").write_text(json.dumps(record), encoding="utf-8")
    assert finished_search(req) is None  # no ppo.json: the search did not end
    (tmp_path / "ppo.json").write_text("{}", encoding="utf-8")
    assert finished_search(req) == record
    others = [
        replace(req, samples=4),
        replace(req, timesteps=2048),
        replace(req, seed=1),
        replace(req, scenario="suite"),
        replace(req, learner="sac"),
    ]
    assert [finished_search(other) for other in others] == [None] * len(others)


def test_a_search_cut_short_is_not_finished(tmp_path: Path) -> None:
    req = TuneRequest(out=tmp_path, samples=3)
    record = {**_record(req, samples=3), "trials": [{"trial": 0}]}  # one trial of three
    (tmp_path / "tune.json").write_text(json.dumps(record), encoding="utf-8")
    (tmp_path / "ppo.json").write_text("{}", encoding="utf-8")
    assert finished_search(req) is None
