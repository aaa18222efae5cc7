"""Run an exported PPO actor with numpy: no torch, and loading never executes code from the file.

The ``.npz`` (``allow_pickle=False``) holds the observation normalisation (``obs_mean``,
``obs_var``, ``obs_clip``, ``obs_eps``), the actor's hidden layers ``w0, b0, w1, b1, …``
(tanh activations, SB3's default for PPO), the action layer ``w_out, b_out`` and a JSON string
``meta`` (scenario, environment keyword arguments (the shipped files name their preset:
:mod:`aeromag_env.environment.config`), training summary); :mod:`.policy_file` reads
it and checks every array (names, dtypes, shapes, finite values, the sizes ``env_kwargs`` give)
before a policy exists, so a malformed file is a one-line
:class:`~aeromag_env.errors.PolicyFileError` at load time, never an error in
:meth:`NumpyPPOPolicy.predict`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from agents.policy_file import read_policy

State = Any


class NumpyPPOPolicy:
    """Deterministic PPO actor: ``clip(W_out tanh(… tanh(W_0 x̂ + b_0) …) + b_out, −1, 1)``.

    Build it with :meth:`load` (which checks the file); the constructor trusts its arrays.
    """

    name = "ppo"

    def __init__(self, arrays: dict[str, np.ndarray], meta: dict[str, Any]) -> None:
        self.mean = arrays["obs_mean"]
        self.std = np.sqrt(arrays["obs_var"] + float(arrays["obs_eps"]))
        self.clip = float(arrays["obs_clip"])
        n_hidden = sum(1 for k in arrays if k.startswith("w") and k[1:].isdigit())
        self.layers = [(arrays[f"w{i}"], arrays[f"b{i}"]) for i in range(n_hidden)]
        self.out = (arrays["w_out"], arrays["b_out"])
        self.meta = meta
        self.n_obs = int(self.mean.shape[-1])

    @classmethod
    def load(cls, path: str | Path) -> NumpyPPOPolicy:
        """Read an exported policy; a missing or malformed file is a one-line
        :class:`~aeromag_env.errors.PolicyFileError` naming the file and the problem."""
        return cls(*read_policy(path))

    @property
    def env_kwargs(self) -> dict[str, Any]:
        """Environment settings the policy was trained with (observation layout, action scale)."""
        return dict(self.meta.get("env_kwargs", {}))

    def make_env(self, scenario: str | None = None, **overrides: Any) -> Any:
        """The environment the policy was trained for, by its registered id
        (``AeroMag/Nonstationary-v0``…) with the policy's :attr:`env_kwargs` (``overrides``
        on top, e.g. ``max_episode_steps``); ``scenario`` defaults to the training scenario."""
        import gymnasium as gym

        from aeromag_env.environment.ids import env_id

        name = scenario or self.meta.get("scenario", "nominal")
        return gym.make(env_id(name), **{**self.env_kwargs, **overrides})

    def predict(
        self,
        obs: np.ndarray,
        state: State = None,
        episode_start: Any = None,
        deterministic: bool = True,
    ) -> tuple[np.ndarray, State]:
        """Actions (n_act,) for one observation (n_obs,), or (N, n_act) for (N, n_obs);
        observations far outside the training statistics saturate (clipped after scaling)."""
        x = np.asarray(obs, dtype=np.float64)
        if x.ndim not in (1, 2) or x.shape[-1] != self.n_obs:
            raise ValueError(
                f"the PPO policy takes {self.n_obs} observations per environment, "
                f"got an array of shape {x.shape}: make the environment with "
                "policy.make_env(), or pass it policy.env_kwargs"
            )
        single = x.ndim == 1
        with np.errstate(over="ignore"):  # a huge observation scales to ±inf, then is clipped
            x = np.clip((np.atleast_2d(x) - self.mean) / self.std, -self.clip, self.clip)
        for w, b in self.layers:
            x = np.tanh(x @ w.T + b)
        action = np.clip(x @ self.out[0].T + self.out[1], -1.0, 1.0).astype(np.float32)
        return (action[0] if single else action), state
