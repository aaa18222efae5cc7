import json

import pytest

from aeromag_env.configs import from_dict, from_json, to_dict, to_json
from aeromag_env.errors import ConfigError
from aeromag_env.simulation.config import PRESETS, SimulationConfig, preset, with_overrides


@pytest.mark.parametrize("name", list(PRESETS))
def test_json_round_trip(name):
    cfg = preset(name)
    assert from_json(SimulationConfig, to_json(cfg)) == cfg
    # a dict that went through JSON (tuples become lists) comes back equal too
    assert from_dict(SimulationConfig, json.loads(json.dumps(to_dict(cfg)))) == cfg
    assert from_dict(SimulationConfig, cfg) is cfg


def test_overrides_and_errors():
    cfg = with_overrides(
        preset("nominal"), {"trajectory.duration_s": 600, "trajectory.pattern": "survey"}
    )
    assert cfg.trajectory.duration_s == 600.0 and cfg.trajectory.pattern == "survey"
    with pytest.raises(ConfigError, match=r"unknown configuration field 'trajectory\.durration_s'"):
        with_overrides(cfg, {"trajectory.durration_s": 1})
    with pytest.raises(
        ConfigError, match="unknown preset 'papr'; valid presets: nominal, paper, noise_free"
    ):
        preset("papr")
    with pytest.raises(ConfigError, match=r"unknown field\(s\) colour"):
        from_dict(SimulationConfig, {"colour": 1})
    with pytest.raises(ConfigError, match="expects a number"):
        from_dict(SimulationConfig, {"earth": {"daily_amplitude_nt": "big"}})
    with pytest.raises(ConfigError, match="white_std_nt must be ≥ 0"):
        from_dict(SimulationConfig, {"fluxgate_noise": {"white_std_nt": -1}})
    with pytest.raises(ConfigError, match="not valid JSON"):
        from_json(SimulationConfig, "{")


def test_presets_say_what_they_are():
    assert preset("paper").fluxgate_noise.white_std_nt == 20.0
    assert preset("paper").fluxgate_noise.fogm_std_nt == 0.0
    assert not preset("paper").scalar.enabled
    nf = preset("noise_free")
    assert nf.fluxgate_noise.white_std_nt == 0 and nf.scalar.noise.white_std_nt == 0
