"""Run an exported actor with numpy: no torch, and loading never executes code from the file.

The ``.npz`` (``allow_pickle=False``) holds the observation normalisation (``obs_mean``,
``obs_var``, ``obs_clip``, ``obs_eps``), for a recurrent policy its LSTM layer, the actor's
hidden layers ``w0, b0, w1, b1, …`` (tanh activations, SB3's default for PPO; ReLU for SAC and
TQC), the action layer ``w_out, b_out`` (clipped to [-1, 1], or through tanh for SAC and TQC)
and a JSON string
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

from agents.policies.policy_file import read_policy

#: A recurrent policy's state: the LSTM's hidden and cell values, each (N, H); None otherwise.
State = Any


def _relu(x: np.ndarray) -> np.ndarray:
    return np.maximum(x, 0.0)


def _sigmoid(x: np.ndarray) -> np.ndarray:
    with np.errstate(over="ignore"):
        return 1.0 / (1.0 + np.exp(-x))


class NumpyPPOPolicy:
    """Deterministic actor: ``head(W_out f(… f(W_0 h + b_0) …) + b_out)`` where ``h`` is the
    normalised observation, or a recurrent policy's LSTM output for it; ``f`` is tanh (PPO) or
    ReLU (SAC, TQC) and ``head`` clips to [-1, 1] (PPO) or is tanh (SAC, TQC).

    A recurrent policy keeps its LSTM state as stable-baselines3's recurrent policies do:
    ``predict`` returns it and takes it back (``state``), and ``episode_start`` (True at an
    episode's first observation) zeroes it. Called with ``state=None`` it continues from the
    state it returned last (zeroed by ``episode_start`` or :meth:`reset`), so a caller that
    ignores the state still gets a policy with memory within the episode.

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
        self.activation = _relu if meta.get("activation") == "relu" else np.tanh
        self.squash = meta.get("head") == "tanh"
        self.lstm = (
            (arrays["lstm_w_ih"], arrays["lstm_w_hh"], arrays["lstm_b"])
            if "lstm_w_ih" in arrays
            else None
        )
        self._state: State = None

    @property
    def recurrent(self) -> bool:
        """Whether the policy has an LSTM (and so a state across steps)."""
        return self.lstm is not None

    def reset(self) -> None:
        """Forget the state kept between calls (a recurrent policy's new episode)."""
        self._state = None

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
        if self.lstm is not None:
            x, state = self._recur(x, state, episode_start)
        for w, b in self.layers:
            x = self.activation(x @ w.T + b)
        z = x @ self.out[0].T + self.out[1]
        action = (np.tanh(z) if self.squash else np.clip(z, -1.0, 1.0)).astype(np.float32)
        return (action[0] if single else action), state

    def _recur(self, x: np.ndarray, state: State, episode_start: Any) -> tuple[np.ndarray, State]:
        """One LSTM step (torch's equations and gate order) from ``state``, zeroed where
        ``episode_start``; returns the output and the new state, which it also keeps."""
        assert self.lstm is not None
        w_ih, w_hh, b = self.lstm
        n, hidden = x.shape[0], w_hh.shape[1]
        if state is None:
            state = self._state
        if state is None or np.shape(state[0]) != (n, hidden):
            h, c = np.zeros((n, hidden)), np.zeros((n, hidden))
        else:
            h, c = np.array(state[0], dtype=np.float64), np.array(state[1], dtype=np.float64)
        if episode_start is not None:
            keep = ~np.broadcast_to(np.asarray(episode_start, dtype=bool).reshape(-1), (n,))
            h, c = h * keep[:, None], c * keep[:, None]
        gates = x @ w_ih.T + h @ w_hh.T + b
        i, f, g, o = np.split(gates, 4, axis=1)
        c = _sigmoid(f) * c + _sigmoid(i) * np.tanh(g)
        h = _sigmoid(o) * np.tanh(c)
        self._state = (h, c)
        return h, (h, c)


#: The same class under the name that says what it is since it runs every learner's export.
NumpyPolicy = NumpyPPOPolicy
