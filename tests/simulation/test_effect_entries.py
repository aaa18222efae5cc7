"""An effect entry of a simulator configuration (``{"name": …, "channel": …, "parameters":
{…}}``, docs/howto/discover.md) either adds a field or is refused in one line naming it."""

from __future__ import annotations

import json

import numpy as np
import pytest

from aeromag_env.configs import from_json
from aeromag_env.errors import ConfigError
from aeromag_env.simulation.config import EffectConfig, SimulationConfig
from aeromag_env.simulation.effects import EFFECTS
from aeromag_env.simulation.simulate import simulate_flight
from tests._helpers import assert_one_line_error, run_cli


def _zero(size: int) -> float | list[float]:
    """A parameter of ``size`` (0: a number; negative: a multiple of ``-size`` numbers), zero."""
    return 0.0 if size == 0 else [0.0] * abs(size)


@pytest.mark.parametrize("name", list(EFFECTS))
def test_an_entry_without_a_strength_is_refused_naming_the_effect(name: str) -> None:
    effect = EFFECTS[name]
    channel = f"{effect.channel_prefixes[0]}a" if effect.channel_prefixes else None
    zeros = {key: _zero(effect.parameter_sizes[key]) for key in effect.strength}
    for parameters in ({}, zeros):
        with pytest.raises(ConfigError) as refused:
            EffectConfig(name=name, channel=channel, parameters=parameters)
        assert_one_line_error(refused, f"effect {name} adds nothing", *effect.strength)


def test_every_effect_names_its_strength_among_its_parameters() -> None:
    for effect in EFFECTS.values():
        assert effect.strength and set(effect.strength) <= set(effect.parameter_sizes), effect.name


def test_the_documented_entry_adds_a_field() -> None:
    """The entry discover.md shows (a 50 ms lag) is read from JSON and adds a field: on two
    minutes of the calibration pattern its largest component is above a nT."""
    entry = {"name": "sensor_lag", "parameters": {"lag_s": 0.05}}
    text = json.dumps({"effects": [entry], "trajectory": {"duration_s": 120.0}})
    cfg = from_json(SimulationConfig, text)
    assert cfg.effects == (EffectConfig(**entry),)
    added = simulate_flight(cfg, 7).vector("truth_effects")
    assert np.abs(added).max() > 1.0  # [nT]


def test_simulate_refuses_a_configuration_with_an_empty_entry(tmp_path, capsys) -> None:
    config = tmp_path / "model.json"
    config.write_text(json.dumps({"effects": [{"name": "sensor_lag"}]}), encoding="utf-8")
    out = tmp_path / "flight.h5"
    assert run_cli(["simulate", "--config", str(config), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "effect sensor_lag adds nothing: give lag_s" in err, err
    assert not out.exists()
