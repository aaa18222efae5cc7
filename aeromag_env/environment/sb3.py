"""stable-baselines3 ``VecEnv`` over the batched environment (needs the ``rl`` extra).

stable-baselines3 does not take Gymnasium vector environments: it has its own ``VecEnv`` API
(``step_async`` / ``step_wait``, a list of info dicts, same-step autoreset with the last
observation in ``info["terminal_observation"]``). :class:`AeroMagSB3VecEnv` serves that API
from one :class:`~aeromag_env.environment.vec_env.AeroMagCompensationVecEnv`, so that training
steps all environments in one compiled call instead of one Python ``step`` per environment
(``DummyVecEnv``). Given the same reset seeds and actions it returns what ``DummyVecEnv`` over
single environments returns (tested), so training is unchanged, only faster.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.vector import AutoresetMode

try:  # the class below subclasses SB3's VecEnv, so SB3 is needed when this module is imported
    from stable_baselines3.common.vec_env.base_vec_env import (
        VecEnv,
        VecEnvIndices,
        VecEnvObs,
        VecEnvStepReturn,
    )
except ImportError as err:  # pragma: no cover - depends on the installed extras
    raise ImportError(
        "aeromag_env.environment.sb3 needs stable-baselines3: pip install 'aeromag_env[rl]'"
    ) from err

from aeromag_env.environment.env import EnvConfig
from aeromag_env.environment.spaces import action_size
from aeromag_env.environment.vec_env import AeroMagCompensationVecEnv

#: What ``step_infos`` may be: every step's infos, or only those of episodes that ended.
STEP_INFOS = ("every", "episode_end")


class AeroMagSB3VecEnv(VecEnv):
    """``num_envs`` environments of ``AeroMagCompensation-v0`` behind SB3's ``VecEnv`` API.

    Parameters
    ----------
    num_envs : number of environments
    config, overrides : the environment configuration (as ``gym.make``)
    reset_seeds : optional, one seed iterator per environment: every reset of environment i
        (the first and each automatic one) takes the next seed of ``reset_seeds[i]`` — what a
        ``DummyVecEnv`` of envs wrapped to reset from a seed stream does (training seeds).
        Without it, ``seed()`` seeds the next reset and environments then draw their flights
        from their own generators.
    prefetch : simulate each environment's next flight in a worker process while the current
        one runs (:mod:`aeromag_env.environment.prefetch`; the same flights, resets cost no
        simulation).
    render_mode : None or ``"rgb_array"``: SB3's ``render()`` tiles one frame per environment.
    step_infos : ``"every"`` (default): every step returns each environment's info, as
        ``DummyVecEnv`` does; ``"episode_end"``: only the environments whose episode ended on the
        step get theirs (with ``terminal_observation`` and ``TimeLimit.truncated``), the others
        an empty dict. SB3's trainers read a step's infos only at episode ends, so training is
        unchanged (tested) and skips building N dicts a step (``agents.training.ppo`` trains so).

    Attributes
    ----------
    venv : the underlying Gymnasium vector environment (autoreset disabled: resets here)
    """

    def __init__(
        self,
        num_envs: int,
        config: EnvConfig | dict | None = None,
        reset_seeds: Sequence[Iterator[int]] | None = None,
        prefetch: bool = False,
        render_mode: str | None = None,
        step_infos: str = "every",
        **overrides: Any,
    ) -> None:
        if step_infos not in STEP_INFOS:
            raise ValueError(f"step_infos must be one of {STEP_INFOS}, got {step_infos!r}")
        self._every_info = step_infos == "every"
        self.venv = AeroMagCompensationVecEnv(
            num_envs,
            config,
            autoreset_mode=AutoresetMode.DISABLED,
            prefetch=prefetch,
            render_mode=render_mode,
            **overrides,
        )
        if reset_seeds is not None and len(reset_seeds) != num_envs:
            raise ValueError(f"reset_seeds needs one iterator per environment ({num_envs})")
        self._seed_streams = list(reset_seeds) if reset_seeds is not None else None
        # the seed each environment's next reset takes (drawn one ahead, to prefetch its flight)
        self._upcoming: list[int | None] = (
            [next(s) for s in self._seed_streams] if self._seed_streams else [None] * num_envs
        )
        self._actions = np.zeros((num_envs, action_size(self.venv.config)))
        self._results = self.venv.results  # the arrays every step leaves its results in
        super().__init__(
            num_envs, self.venv.single_observation_space, self.venv.single_action_space
        )

    def reset(self) -> VecEnvObs:
        options = self._options[0]
        if any(o != options for o in self._options):
            raise ValueError("reset options must be the same for every environment")
        obs, infos = self.venv.reset(seed=self._next_seeds(self._seeds), options=options)
        self.reset_infos = _info_list(infos, self.num_envs)
        for i in range(self.num_envs):
            self.venv.prefetch_next(i, self._upcoming[i])
        self._reset_seeds()
        self._reset_options()
        return obs

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = actions

    def step_wait(self) -> VecEnvStepReturn:
        ended = self.venv.step_in_place(self._actions)  # one compiled call does the step
        results = self._results
        obs, dones = results.obs.copy(), results.ended.copy()
        rewards = results.reward.astype(np.float32)
        if self._every_info:
            info_list = self.venv.info_rows()
            limits = (results.truncated & ~results.terminated).tolist()
            for info, limit in zip(info_list, limits, strict=True):
                info["TimeLimit.truncated"] = limit
        else:  # SB3's trainers read infos at episode ends only
            info_list = [{} for _ in range(self.num_envs)]
        if ended:
            obs = self._end_episodes(obs, dones, info_list)
        return obs, rewards, dones, info_list

    def _end_episodes(
        self, obs: np.ndarray, dones: np.ndarray, info_list: list[dict[str, Any]]
    ) -> np.ndarray:
        """The environments of ``dones`` ended on this step: their infos (with
        ``TimeLimit.truncated``, unless every info has it already, and ``terminal_observation``
        from ``obs``), and reset (the next flights already prefetched). Returns the
        observations with those of the new flights."""
        ended = np.flatnonzero(dones)
        if not self._every_info:
            results = self.venv.results
            limits = (results.truncated[ended] & ~results.terminated[ended]).tolist()
            rows = self.venv.info_rows(ended)
            for i, row, limit in zip(ended.tolist(), rows, limits, strict=True):
                row["TimeLimit.truncated"] = limit
                info_list[i] = row
        for i in ended.tolist():
            info_list[i]["terminal_observation"] = obs[i].copy()
        seeds = self._next_seeds([None] * self.num_envs, dones)
        obs, reset_infos = self.venv.reset(seed=seeds, options={"reset_mask": dones})
        for i, info in zip(
            ended.tolist(), _info_list(reset_infos, self.num_envs, ended), strict=True
        ):
            self.reset_infos[i] = info
            self.venv.prefetch_next(i, self._upcoming[i])
        return obs

    def close(self) -> None:
        self.venv.close()

    def get_images(self) -> Sequence[np.ndarray | None]:
        """One frame per environment (``render_mode="rgb_array"``; SB3's ``render`` tiles them)."""
        frames = self.venv.render()
        return [None] * self.num_envs if frames is None else list(frames)

    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        """The vector environment's attribute (shared by all environments), once per index."""
        return [getattr(self.venv, attr_name)] * len(list(self._get_indices(indices)))

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        raise AttributeError("the batched environments share their attributes; set them on venv")

    def env_method(
        self, method_name: str, *method_args: Any, indices: VecEnvIndices = None, **kwargs: Any
    ) -> list[Any]:
        raise AttributeError("the batched environments are no separate objects; use venv")

    def env_is_wrapped(
        self, wrapper_class: type[gym.Wrapper], indices: VecEnvIndices = None
    ) -> list[bool]:
        return [False] * len(list(self._get_indices(indices)))

    def _next_seeds(
        self, seeds: list[int | None], mask: np.ndarray | None = None
    ) -> list[int | None]:
        """The seeds of the environments being reset: from the streams when given."""
        if self._seed_streams is None:
            return seeds
        chosen = range(self.num_envs) if mask is None else np.flatnonzero(mask).tolist()
        out: list[int | None] = [None] * self.num_envs
        for i in chosen:
            out[i], self._upcoming[i] = self._upcoming[i], next(self._seed_streams[i])
        return out


def _info_list(
    infos: dict[str, Any], n: int, indices: Sequence[int] | np.ndarray | None = None
) -> list[dict[str, Any]]:
    """Gymnasium's batched infos (arrays with ``_key`` masks) → one dict per environment
    (for ``indices``, default all), with Python scalars as a single env returns them."""
    rows = range(n) if indices is None else indices
    out: list[dict[str, Any]] = [{} for _ in rows]
    for key, values in infos.items():
        if key.startswith("_"):
            continue
        mask, items = infos[f"_{key}"], values.tolist()
        for info, i in zip(out, rows, strict=True):
            if mask[i]:
                info[key] = items[i]
    return out
