"""Run an exported PPO actor with numpy: no torch, and loading never executes code from the file.

The ``.npz`` (``allow_pickle=False``) holds the observation normalisation (``obs_mean``,
``obs_var``, ``obs_clip``, ``obs_eps``), the actor's hidden layers ``w0, b0, w1, b1, …``
(tanh activations, SB3's default for PPO), the action layer ``w_out, b_out`` and a JSON string
``meta`` (scenario, environment keyword arguments, training summary).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from aeromag_env.errors import AeromagError

State = Any


class NumpyPPOPolicy:
    """Deterministic PPO actor: ``clip(W_out tanh(… tanh(W_0 x̂ + b_0) …) + b_out, −1, 1)``."""

    name = "ppo"

    def __init__(self, arrays: dict[str, np.ndarray], meta: dict[str, Any]) -> None:
        self.mean = arrays["obs_mean"]
        self.std = np.sqrt(arrays["obs_var"] + float(arrays["obs_eps"]))
        self.clip = float(arrays["obs_clip"])
        n_hidden = sum(1 for k in arrays if k.startswith("w") and k[1:].isdigit())
        self.layers = [(arrays[f"w{i}"], arrays[f"b{i}"]) for i in range(n_hidden)]
        self.out = (arrays["w_out"], arrays["b_out"])
        self.meta = meta

    @classmethod
    def load(cls, path: str | Path) -> NumpyPPOPolicy:
        """Read an exported policy; a missing or malformed file is a one-line error."""
        try:
            with np.load(Path(path), allow_pickle=False) as data:
                arrays = {k: data[k] for k in data.files}
            meta = json.loads(str(arrays.pop("meta")))
            return cls(arrays, meta)
        except (OSError, KeyError, ValueError) as e:
            raise AeromagError(f"cannot load PPO policy {path}: {e}") from None

    @property
    def env_kwargs(self) -> dict[str, Any]:
        """Environment settings the policy was trained with (observation layout, action scale)."""
        return dict(self.meta.get("env_kwargs", {}))

    def predict(self, obs: np.ndarray, state: State = None, episode_start: Any = None,
                deterministic: bool = True) -> tuple[np.ndarray, State]:  # fmt: skip
        x = np.asarray(obs, dtype=np.float64)
        single = x.ndim == 1
        x = np.clip((np.atleast_2d(x) - self.mean) / self.std, -self.clip, self.clip)
        for w, b in self.layers:
            x = np.tanh(x @ w.T + b)
        action = np.clip(x @ self.out[0].T + self.out[1], -1.0, 1.0).astype(np.float32)
        return (action[0] if single else action), state
