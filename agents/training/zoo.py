"""Our PPO hyperparameters as an RL Baselines3 Zoo (rl_zoo3) file, made from ``ppo.json``.

``agents/training/hyperparams/ppo.json`` stays the one place the hyperparameters are written;
``agents/training/hyperparams/ppo_zoo.yml`` is made from it by ``python -m agents.training.zoo`` (a
test checks that the two agree). Each scenario's entry goes under the registered id of its training
scenario (``AeroMag/NonstationaryDense-v0``: :mod:`aeromag_env.environment.ids`) with its
``env_kwargs``, the observation and reward normalisation of ``aeromag train``
(:func:`agents.training.ppo.normalized`), the network and initial log std, and a Monitor that
records each episode's RMSE. What the zoo cannot do: the behaviour-cloning pretraining of version 5
(the zoo trains PPO from scratch, as version 4 did), validation on our validation seeds and the
numpy export; ``aeromag train`` does those.

Train with it::

    python -m rl_zoo3.train --algo ppo --env AeroMag/NonstationaryDense-v0 \\
        --gym-packages aeromag_env --conf-file agents/training/hyperparams/ppo_zoo.yml
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from aeromag_env.environment.ids import env_id
from agents.training.hyperparams_file import read_hyperparams
from agents.training.ppo_hyperparams import SB3_PPO_KEYS, PPOHyperparams

HYPERPARAMS = Path(__file__).parent / "hyperparams"
#: Timesteps of the shipped policy's training run (``aeromag train --timesteps``).
ZOO_TIMESTEPS = 1_500_000
#: PPO's own settings, copied as they are.
_PPO_KEYS = ("n_envs", *SB3_PPO_KEYS)
#: Clip of the normalised observations (as :func:`agents.training.ppo.normalized`).
CLIP_OBS = 10.0


def zoo_hyperparams(hyperparams: dict[str, Any]) -> dict[str, dict[str, Any]]:
    """The rl_zoo3 hyperparameters (one entry per env id) of a checked ``ppo.json``."""
    out: dict[str, dict[str, Any]] = {}
    for scenario, given in hyperparams["scenarios"].items():
        hp = PPOHyperparams.from_entry(given)
        entry: dict[str, Any] = {"policy": "MlpPolicy", "n_timesteps": float(ZOO_TIMESTEPS)}
        entry.update({key: getattr(hp, key) for key in _PPO_KEYS})
        entry["normalize"] = (
            f"dict(norm_obs=True, norm_reward={hp.normalize_reward}, clip_obs={CLIP_OBS})"
        )
        policy = (
            f"net_arch={list(hp.net_arch)}, optimizer_kwargs=dict(eps=1e-05), "
            f"log_std_init={float(hp.log_std_init)}"
        )
        entry["policy_kwargs"] = f"dict({policy})"
        entry["monitor_kwargs"] = "dict(info_keywords=('episode_rmse_nt', 'divergences'))"
        entry["env_kwargs"] = hp.to_entry()["env_kwargs"]
        out[env_id(hp.train_scenario or scenario)] = entry
    return out


def write_zoo_file(source: Path, target: Path) -> Path:
    """Write ``target`` (YAML) from the hyperparameter file ``source``."""
    import yaml

    hyperparams = read_hyperparams(source)
    head = (
        f"# Made from {source.name} (version {hyperparams['version']}) by "
        "`python -m agents.training.zoo`: edit that file, not this one.\n# rl_zoo3 trains PPO "
        "from scratch: no behaviour-cloning pretraining (agents/zoo.py).\n"
    )
    body = yaml.safe_dump(zoo_hyperparams(hyperparams), sort_keys=False, default_flow_style=None)
    target.write_text(head + body, encoding="utf-8")
    return target


#: rl_zoo3's name of each learner of ``learners.json`` (CMA-ES is not an rl_zoo3 algorithm).
ZOO_ALGOS = {"recurrent_ppo": "ppo_lstm", "sac": "sac", "tqc": "tqc"}


def learner_zoo_hyperparams(learner: str, source: Path) -> dict[str, dict[str, Any]]:
    """The rl_zoo3 entry (under ``AeroMag/Suite-v0``) of ``learner`` in ``learners.json``."""
    from agents.training.learners import SCENARIO, learner_hyperparams

    hp = learner_hyperparams(learner, source)
    policy = "MlpLstmPolicy" if learner == "recurrent_ppo" else "MlpPolicy"
    entry: dict[str, Any] = {"policy": policy, "n_timesteps": float(hp["timesteps"])}
    entry["n_envs"] = hp["n_envs"]
    entry.update(hp["algo"])
    entry["normalize"] = (
        f"dict(norm_obs=True, norm_reward={hp['normalize_reward']}, clip_obs={CLIP_OBS})"
    )
    kwargs = ", ".join(f"{k}={v!r}" for k, v in hp.get("policy_kwargs", {}).items())
    entry["policy_kwargs"] = f"dict({kwargs})"
    entry["monitor_kwargs"] = "dict(info_keywords=('episode_rmse_nt', 'divergences'))"
    entry["env_kwargs"] = dict(hp["env_kwargs"])
    return {env_id(SCENARIO): entry}


def write_learner_zoo_files(source: Path, folder: Path) -> list[Path]:
    """Write ``folder/<zoo algo>.yml`` for each learner of ``source`` rl_zoo3 knows."""
    import yaml

    written = []
    for learner, algo in ZOO_ALGOS.items():
        head = (
            f"# Made from {source.name} by `python -m agents.training.zoo`: edit that file, not "
            "this "
            f"one.\n# python -m rl_zoo3.train --algo {algo} --env {env_id('suite')} "
            f"--gym-packages aeromag_env --conf-file agents/training/hyperparams/{algo}.yml\n"
        )
        body = yaml.safe_dump(
            learner_zoo_hyperparams(learner, source), sort_keys=False, default_flow_style=None
        )
        target = folder / f"{algo}.yml"
        target.write_text(head + body, encoding="utf-8")
        written.append(target)
    return written


def main(argv: list[str] | None = None) -> int:
    about = (__doc__ or "").split("\n")[0]
    parser = argparse.ArgumentParser(prog="python -m agents.training.zoo", description=about)
    parser.add_argument("target", nargs="?", default=str(HYPERPARAMS / "ppo_zoo.yml"))
    parser.add_argument("--source", default=str(HYPERPARAMS / "ppo.json"))
    args = parser.parse_args(argv)
    print(f"wrote {write_zoo_file(Path(args.source), Path(args.target))}")
    folder = Path(args.target).parent
    for path in write_learner_zoo_files(HYPERPARAMS / "learners.json", folder):
        print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
