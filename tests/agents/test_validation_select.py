"""How a training run picks its best checkpoint (``select_by``), with stand-in RMSEs."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from aeromag_env.environment.ids import SUITE
from agents.training import validation
from agents.training.validation import Validator

#: Stand-in RMSE per (policy, scenario) [nT]: the candidate beats the tuned constant on every
#: scenario but one, where it is 1.5× worse; the mean over flights hides that.
RMSE = {
    "tuned_constant": dict.fromkeys(SUITE, 2.0),
    "privileged": dict.fromkeys(SUITE, 1.0),
    "candidate": {**dict.fromkeys(SUITE, 1.2), "manoeuvre_heavy": 3.0},
}


@pytest.fixture
def runs(monkeypatch: pytest.MonkeyPatch) -> list[tuple[str, str, int]]:
    calls: list[tuple[str, str, int]] = []

    def fake(policy: Any, scenario: str, episodes: int, env_kwargs: Any = None) -> np.ndarray:
        name = policy if isinstance(policy, str) else "candidate"
        calls.append((name, scenario, episodes))
        lookup = RMSE[name].get(scenario, RMSE[name]["nonstationary"])
        return np.full(episodes, lookup)

    monkeypatch.setattr(validation, "validation_rmse", fake)
    return calls


def test_worst_scenario_ratio_names_the_scenario_a_mean_hides(runs) -> None:
    v = Validator("worst_ratio_to_tuned_constant", "suite", 56)
    assert v.flights() == dict.fromkeys(SUITE, 8)
    point = v(object())
    assert point["validation_score"] == pytest.approx(1.5)  # manoeuvre_heavy: 3.0 / 2.0
    assert point["validation_ratio"]["paper"] == pytest.approx(0.6)
    mean_ratio = np.mean(list(point["validation_ratio"].values()))
    assert mean_ratio < 1.0  # what a mean over the scenarios would have accepted
    v(object())  # a second checkpoint: the references are not run again
    assert sum(name == "tuned_constant" for name, _, _ in runs) == len(SUITE)
    assert sum(name == "candidate" for name, _, _ in runs) == 2 * len(SUITE)


def test_ratio_to_privileged_and_rmse_keep_their_meaning(runs) -> None:
    point = Validator("ratio_to_privileged", "nonstationary", 10)(object())
    assert point["validation_score"] == pytest.approx(1.2)
    assert point["validation_rmse_nt"] == pytest.approx(1.2)
    assert "validation_score" not in Validator("rmse", "nonstationary", 10)(object())
    assert {s for _, s, _ in runs} == {"nonstationary"}


def test_an_unknown_rule_is_refused() -> None:
    with pytest.raises(ValueError, match="select_by must be one of"):
        Validator("best_guess", "suite", 56)
