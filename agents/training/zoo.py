"""Our hyperparameters as RL Baselines3 Zoo (rl_zoo3) files, made from ``ppo.json`` and
``learners.json``, and the wrapper that gives the zoo's evaluation environments their settings.

``agents/training/hyperparams/ppo.json`` stays the one place the hyperparameters are written;
``agents/training/hyperparams/ppo_zoo.yml`` is made from it by ``python -m agents.training.zoo``
(a test checks that the two agree). Each scenario's entry goes under the registered id of its
training scenario (``AeroMag/NonstationaryDense-v0``: :mod:`aeromag_env.environment.ids`) with
its ``env_kwargs`` (a preset), the observation and reward normalisation of ``aeromag train``
(:func:`agents.training.ppo.normalized`), the network and initial log std, a Monitor that
records each episode's RMSE, and :class:`RecipeSettings` as its ``env_wrapper`` with the same
settings: rl_zoo3 gives a recipe's ``env_kwargs`` to its training environments only, and would
make its evaluation environments (every 25 000 steps by default) with the registered id's
``paper`` preset, whose two observations the policy cannot read. What the zoo cannot do: the
behaviour-cloning pretraining (the zoo trains PPO from scratch), validation on our validation
seeds and the numpy export; ``aeromag train`` does those.

Train with it::

    python -m rl_zoo3.train --algo ppo --env AeroMag/NonstationaryDense-v0 \\
        --gym-packages aeromag_env --conf-file agents/training/hyperparams/ppo_zoo.yml
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any, cast

import gymnasium as gym

from aeromag_env.environment.ids import env_id
from aeromag_env.quick import quick_requested

HYPERPARAMS = Path(__file__).parent / "hyperparams"
#: Timesteps of the shipped policy's training run (``aeromag train --timesteps``).
ZOO_TIMESTEPS = 1_500_000
#: Clip of the normalised observations (as :func:`agents.training.ppo.normalized`).
CLIP_OBS = 10.0
#: The wrapper rl_zoo3 puts on every environment it makes (``env_wrapper``).
WRAPPER = "agents.training.zoo.RecipeSettings"


class RecipeSettings(gym.Wrapper):
    """An environment rl_zoo3 makes, with the recipe's environment settings.

    rl_zoo3 (2.9) gives a recipe's ``env_kwargs`` to its training environments only; its
    evaluation environments are made from the registered id alone. ``env_wrapper`` is the
    recipe's one hook that rl_zoo3 applies to every environment it makes, so a recipe names its
    settings here again (``env_wrapper: [{agents.training.zoo.RecipeSettings: {preset:
    general}}]``): an environment made with other settings is made again from its id with
    these, under the Monitor rl_zoo3 put on it (which keeps its file and its episode records);
    one made with them is kept as it is.

    Parameters
    ----------
    env : the environment rl_zoo3 made, in its Monitor
    settings : the recipe's ``env_kwargs`` (a preset and fields,
        :func:`aeromag_env.environment.config.env_config`)
    """

    def __init__(self, env: gym.Env, **settings: Any) -> None:
        spec = env.spec
        if spec is None:
            raise ValueError("RecipeSettings wraps an environment made from a registered id")
        made = gym.make(spec.id, **settings)  # the id's scenario, the recipe's settings
        if _config(made) == _config(env):
            made.close()
        else:
            _replace_inner(env, made)
        super().__init__(env)


def _config(env: gym.Env) -> Any:
    """The settings of the environment under ``env``'s wrappers."""
    return cast(Any, env.unwrapped).config


def _replace_inner(env: gym.Env, made: gym.Env) -> None:
    """Put ``made`` under the outermost wrapper of ``env`` (rl_zoo3's Monitor), closing the
    environment it replaces."""
    if not isinstance(env, gym.Wrapper):
        raise ValueError("RecipeSettings wraps the Monitor rl_zoo3 puts on an environment")
    env.env.close()
    env.env = made


#: What the files say of their ``env_wrapper``.
_WRAPPER_NOTE = (
    "# env_wrapper gives the evaluation environments the env_kwargs (rl_zoo3 gives them to the "
    "training\n# environments only).\n"
)


def _wrapper(settings: dict[str, Any]) -> list[dict[str, Any]]:
    """The recipe's ``env_wrapper``: :class:`RecipeSettings` with ``settings``."""
    return [{WRAPPER: dict(settings)}]


def zoo_hyperparams(table: Any) -> dict[str, dict[str, Any]]:
    """The rl_zoo3 hyperparameters (one entry per env id) of a checked ``ppo.json`` (a
    :class:`~agents.training.hyperparameters.PPOFile`)."""
    from agents.training.hyperparameters import SB3_PPO_KEYS

    out: dict[str, dict[str, Any]] = {}
    for scenario, hp in table.scenarios.items():
        entry: dict[str, Any] = {"policy": "MlpPolicy", "n_timesteps": float(ZOO_TIMESTEPS)}
        entry.update({key: getattr(hp, key) for key in ("n_envs", *SB3_PPO_KEYS)})
        entry["normalize"] = (
            f"dict(norm_obs=True, norm_reward={hp.normalize_reward}, clip_obs={CLIP_OBS})"
        )
        policy = (
            f"net_arch={list(hp.net_arch)}, optimizer_kwargs=dict(eps=1e-05), "
            f"log_std_init={float(hp.log_std_init)}"
        )
        entry["policy_kwargs"] = f"dict({policy})"
        entry["monitor_kwargs"] = "dict(info_keywords=('episode_rmse_nt', 'divergences'))"
        entry["env_kwargs"] = dict(hp.env_kwargs)
        entry["env_wrapper"] = _wrapper(hp.env_kwargs)
        out[env_id(hp.train_scenario or scenario)] = entry
    return out


def write_zoo_file(source: Path, target: Path) -> Path:
    """Write ``target`` (YAML) from the hyperparameter file ``source``."""
    import yaml

    from agents.training.hyperparams_file import read_ppo

    table = read_ppo(source)
    head = (
        f"# Made from {source.name} (version {table.version}) by "
        "`python -m agents.training.zoo`: edit that file, not this one.\n# rl_zoo3 trains PPO "
        "from scratch: no behaviour-cloning pretraining (agents/training/zoo.py).\n"
        f"{_WRAPPER_NOTE}"
    )
    body = yaml.safe_dump(zoo_hyperparams(table), sort_keys=False, default_flow_style=None)
    target.write_text(head + body, encoding="utf-8")
    return target


#: rl_zoo3's name of each learner of ``learners.json`` (CMA-ES is not an rl_zoo3 algorithm).
ZOO_ALGOS = {"recurrent_ppo": "ppo_lstm", "sac": "sac", "tqc": "tqc"}


def learner_zoo_hyperparams(learner: str, source: Path) -> dict[str, dict[str, Any]]:
    """The rl_zoo3 entry (under ``AeroMag/Suite-v0``) of ``learner`` in ``learners.json``."""
    from agents.training.learner_hyperparameters import CMAESHyperparams
    from agents.training.learners import SCENARIO, learner_hyperparams, sb3_keywords

    hp = learner_hyperparams(learner, source)
    if isinstance(hp, CMAESHyperparams):
        raise ValueError("CMA-ES is no rl_zoo3 algorithm")
    policy = "MlpLstmPolicy" if learner == "recurrent_ppo" else "MlpPolicy"
    entry: dict[str, Any] = {"policy": policy, "n_timesteps": float(hp.timesteps)}
    entry["n_envs"] = hp.n_envs
    keywords = sb3_keywords(hp)
    network = keywords.pop("policy_kwargs")
    entry.update(keywords)
    entry["normalize"] = (
        f"dict(norm_obs=True, norm_reward={hp.normalize_reward}, clip_obs={CLIP_OBS})"
    )
    entry["policy_kwargs"] = f"dict({', '.join(f'{k}={v!r}' for k, v in network.items())})"
    entry["monitor_kwargs"] = "dict(info_keywords=('episode_rmse_nt', 'divergences'))"
    entry["env_kwargs"] = dict(hp.env_kwargs)
    entry["env_wrapper"] = _wrapper(hp.env_kwargs)
    return {env_id(SCENARIO): entry}


def write_learner_zoo_files(source: Path, folder: Path) -> list[Path]:
    """Write ``folder/<zoo algo>.yml`` for each learner of ``source`` rl_zoo3 knows."""
    import yaml

    written = []
    for learner, algo in ZOO_ALGOS.items():
        head = (
            f"# Made from {source.name} by `python -m agents.training.zoo`: edit that file, not "
            f"this one.\n{_WRAPPER_NOTE}# python -m rl_zoo3.train --algo {algo} --env "
            f"{env_id('suite')} --gym-packages aeromag_env --conf-file "
            f"agents/training/hyperparams/{algo}.yml\n"
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
    parser.add_argument(
        "target",
        nargs="?",
        help="write only this recipe, to this file: PPO's (of --source), or with --learner that "
        "learner's; without it, every shipped recipe is rewritten in agents/training/hyperparams/ "
        f"(ppo_zoo.yml from ppo.json, {', '.join(f'{a}.yml' for a in ZOO_ALGOS.values())} from "
        "learners.json)",
    )
    parser.add_argument("--source", default=str(HYPERPARAMS / "ppo.json"))
    parser.add_argument(
        "--learner", choices=list(ZOO_ALGOS), help="the recipe of this learner (learners.json)"
    )
    parser.add_argument(
        "--quick",
        action="store_true",
        help="a recipe to try, at the --quick sizes of aeromag train (also with AEROMAG_QUICK=1)",
    )
    args = parser.parse_args(argv)
    if args.target is None:
        if args.learner or args.quick:
            parser.error("--learner and --quick write a recipe to TARGET, never the shipped ones")
        print(f"wrote {write_zoo_file(Path(args.source), HYPERPARAMS / 'ppo_zoo.yml')}")
        for path in write_learner_zoo_files(HYPERPARAMS / "learners.json", HYPERPARAMS):
            print(f"wrote {path}")
        return 0
    target = Path(args.target)
    if args.learner is None:
        write_zoo_file(Path(args.source), target)
    else:
        recipe = learner_zoo_hyperparams(args.learner, HYPERPARAMS / "learners.json")
        _write_recipe(target, recipe, f"# The {args.learner} recipe of learners.json\n")
    if args.quick or quick_requested():
        _write_recipe(target, _quick_recipe(target), QUICK_NOTE)
    print(f"wrote {target}")
    return 0


#: The first line of a quick recipe.
QUICK_NOTE = (
    "# A recipe to try, at the --quick sizes of aeromag train (agents/training/quick.py): not "
    "for training a policy.\n"
)


def _write_recipe(target: Path, recipe: dict[str, Any], head: str) -> None:
    import yaml

    body = yaml.safe_dump(recipe, sort_keys=False, default_flow_style=None)
    target.write_text(head + body, encoding="utf-8")


def _quick_recipe(path: Path) -> dict[str, Any]:
    """The recipes of the file ``path`` at the quick sizes (:data:`agents.training.quick.QUICK`):
    its steps, environments and rollouts."""
    import yaml

    from agents.training.quick import QUICK

    recipes = yaml.safe_load(path.read_text(encoding="utf-8"))
    for entry in recipes.values():
        entry["n_timesteps"] = float(QUICK.train_timesteps)
        entry.update({k: QUICK.ppo[k] for k in ("n_envs", "n_steps", "batch_size") if k in entry})
    return dict(recipes)


if __name__ == "__main__":
    sys.exit(main())
