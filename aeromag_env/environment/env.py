"""The Gymnasium environment ``AeroMagCompensation-v0``: tune the compensator's Q and R online."""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from aeromag_env.compensation.arrays import packed
from aeromag_env.compensation.kalman import FilterState
from aeromag_env.environment import kernels
from aeromag_env.environment.checks import RESET_OPTIONS, reset_options
from aeromag_env.environment.config import ActionSpec, EnvConfig, RewardSpec, env_config
from aeromag_env.environment.info import info
from aeromag_env.environment.layout import (
    N_RUN,
    N_STEP_PAR,
    OUT,
    RUN,
    STEP_PAR,
    EnvArrays,
    EnvSettings,
    RewardForm,
)
from aeromag_env.environment.scenarios import Episode, make_episode
from aeromag_env.environment.spaces import (
    action_size,
    check_actions,
    observation_bounds,
    observation_positions,
)
from aeromag_env.errors import ConfigError

__all__ = ["ActionSpec", "AeroMagCompensationEnv", "EnvConfig", "RewardSpec", "env_config"]


def parameters(config: EnvConfig) -> np.ndarray:
    """The settings of ``config`` the compiled step reads, as a float vector (N_STEP_PAR,)
    laid out by :data:`aeromag_env.environment.layout.STEP_PAR`."""
    act, reward, par = config.action, config.reward, np.zeros(N_STEP_PAR)
    par[STEP_PAR.k] = config.decision_window
    par[STEP_PAR.recent] = config.recent_samples or config.decision_window
    par[STEP_PAR.log_s_max] = math.log(act.s_max)
    par[STEP_PAR.log_limit] = math.log(act.scale_limit)
    par[STEP_PAR.absolute] = float(act.mode == "absolute")
    par[STEP_PAR.q_lo], par[STEP_PAR.q_hi] = act.q_log10
    par[STEP_PAR.r_lo], par[STEP_PAR.r_hi] = act.r_log10
    par[STEP_PAR.qp_lo], par[STEP_PAR.qp_hi] = act.qp_log10
    par[STEP_PAR.split_q] = float(act.permanent != "joint")
    par[STEP_PAR.qp_gate] = float(act.permanent == "gate")
    par[STEP_PAR.reward_nt] = reward.scale_nt
    par[STEP_PAR.reward_form] = RewardForm[reward.form.upper()]
    par[STEP_PAR.penalty] = reward.divergence_penalty
    return par


def step_settings(config: EnvConfig) -> EnvSettings:
    """What the compiled step of every environment of ``config`` shares: the parameters, the
    observation layout and its bounds."""
    low, high = observation_bounds(config)
    return EnvSettings(parameters(config), observation_positions(config), low, high)


class AeroMagCompensationEnv(gym.Env):
    """Online tuning of the 21-state aeromagnetic Kalman compensator's noise covariances.

    ## Description

    One episode is one simulated flight of the chosen scenario (see
    :mod:`aeromag_env.environment.scenarios`). The flight and its signals are generated in
    ``reset``; each ``step`` rescales the filter's process noise Q and measurement noise R (the
    paper's eq. 21, ``Q ← s_a Q``, ``R ← s_r R``) and advances the filter over one decision window
    of K samples. The paper's fuzzy rules are one policy for this task
    (:class:`agents.policies.baselines.FisPolicy`); others are learned. The step is compiled
    (:func:`aeromag_env.environment.kernels.env_step`) and is the same code that
    ``gym.make_vec("AeroMagCompensation-v0", num_envs=N)`` runs for N environments at once
    (:class:`aeromag_env.environment.vec_env.AeroMagCompensationVecEnv`).

    ## Action Space

    ``Box(-1, 1, (2,), float32)``: ``[a_q, a_r]`` → ``s_a = s_max ** a_q``, ``s_r = s_max ** a_r``
    (log scale; ``s_max = 2`` by default, so one step at most doubles or halves Q or R). Values
    outside [-1, 1] are clipped; a non-finite action, or one that is not real numbers (complex,
    bool, text, objects), raises ``ValueError``. The cumulative scales are kept within
    ``[1/scale_limit, scale_limit]`` of the initial Q and R. The mapping is the configuration's
    :class:`~aeromag_env.environment.config.ActionSpec`: with ``mode="absolute"`` an action sets
    the log scale within a fixed range instead; with ``permanent="graded"`` the space is
    ``(3,)``: ``[a_q, a_r, a_qp]``, where ``a_qp`` scales the Q of the permanent-field states
    T_p and ``a_q`` that of the other 18; with ``permanent="gate"`` only the sign of ``a_qp``
    counts (T_p's Q at the top or the bottom of its range).

    ## Observation Space

    ``Box(low, high, (len(observations),), float32)``: the observations the configuration
    names (:attr:`~aeromag_env.environment.config.EnvConfig.observations`), in that order, each
    an entry of the registry :mod:`aeromag_env.environment.observations` (its meaning, unit and
    bounds). The ``paper`` preset gives the paper's two inputs at the end of the window:

    | index | observation | meaning |
    |---|---|---|
    | 0 | log10 ROR | windowed innovation trace over its predicted trace (eq. 22), 0 before data |
    | 1 | log10 QOQ | ``tr(K C_r Kᵀ) / tr Q`` (covariance matching), 0 before data |

    Every configuration starts with these two; the ``nonstationary`` and ``general`` presets
    (:mod:`aeromag_env.environment.config`) add the scales, innovation statistics and the turn
    rate their shipped policies read. Names and columns:
    :func:`aeromag_env.environment.spaces.observation_names` and
    :func:`~aeromag_env.environment.spaces.observation_index` (actions:
    :data:`~aeromag_env.environment.spaces.ACTIONS`).

    ## Rewards

    ``r = −ln(1 + e_w / scale_nt)`` with ``e_w`` the RMS over the window of the true
    interference minus the filter's a-priori estimate (pooled over axes) [nT]; the
    configuration's :class:`~aeromag_env.environment.config.RewardSpec` ``form="linear"`` gives
    ``−e_w / scale_nt`` and ``"squared"`` ``−(e_w / scale_nt)²``.
    The truth is known in simulation only: consistency alone can be met without accuracy
    (scaling Q and R together moves ROR but leaves the estimate unchanged), so the reward is
    accuracy. On the step where the filter diverges the reward is ``divergence_penalty`` (−10).

    ## Starting State

    A new flight of the scenario, drawn from ``reset``'s seed (``options={"scenario": name}``
    switches scenario; ``options={"filter_method": m}`` runs the filter with the built-in
    adaptation of the :class:`~aeromag_env.compensation.model.FilterConfig` method ``m``, e.g.
    ``sage-husa`` or ``ding`` for the classical baselines, for that episode; other option keys,
    or options that are not a dict, are refused), with the scenario's initial Q, R, P and x;
    the first observation is zeros.

    ## Episode End

    ``truncated`` at the end of the flight; ``terminated`` when the filter diverges (non-finite
    or absurd state, non-finite or non-positive-definite covariance, or a whole window of
    outliers that shift the data: :mod:`aeromag_env.compensation.consistency`).

    ## Arguments

    ``gym.make("AeroMagCompensation-v0", config=EnvConfig(...) or dict, preset=name,
    render_mode=None | "rgb_array")``; a complete ``EnvConfig`` replaces the preset (``paper``
    unless named), a dict or keywords (``scenario=``, ``decision_window=``, ``observations=``,
    ``action={...}``) change it (:func:`~aeromag_env.environment.config.env_config`; the flat
    keys of the first version, ``extras=True``…, are read from old files only:
    :mod:`aeromag_env.environment.legacy`). ``info``
    (:data:`aeromag_env.environment.info.INFO`) holds ``rmse_window_nt``, ``ror``, ``qoq``,
    ``q_scale``, ``r_scale``, ``q_permanent_scale`` (1 without a T_p action), ``sample``,
    ``flight_seed``, and the episode's totals so far — at every step, so that the step on which
    a ``TimeLimit`` (``gym.make(..., max_episode_steps=N)``) cuts the episode carries them:
    ``episode_rmse_nt`` (over the flight after ``score_from``; over the part flown when the
    episode ends before it), ``divergences`` and ``outliers_rejected`` (samples the filter's
    outlier gate skipped: a spike or a burst of noise in the fluxgate; 0 on a clean flight).

    ## Version History

    * v0: first version.
    * v0, second revision (the ids unchanged): the observations over the filter's statistics
      window (``whiteness``, ``log_innovation_power``, ``log_step_statistic``,
      ``log_innovation_bias``) are computed from running sums
      (:mod:`aeromag_env.environment.window_sums`) instead of a loop over the window at every
      step. They may differ from the first revision's in their last bits: about 1e-12
      relative before the float32 rounding, at most one float32 unit in the last place
      (whiteness: 1e-8) as observations; on the recorded test episodes not at all. The action
      mapping, rewards, infos, the filter and the episode ends are bitwise as before. A bitwise
      change accepted for speed (the vector environment's step became one compiled call); the
      shipped policies re-evaluated on it (every scenario, 30 test flights): every published
      number as before.
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 4}  # noqa: RUF012 (gymnasium API)

    def __init__(
        self,
        config: EnvConfig | dict | None = None,
        render_mode: str | None = None,
        **overrides: Any,
    ) -> None:
        said = (
            config.get("scenario")
            if isinstance(config, dict)
            else getattr(config, "scenario", None)
        )
        if said is not None and "scenario" in overrides and overrides["scenario"] != said:
            raise ConfigError(
                f"scenario given twice: {overrides['scenario']!r} by the id or keyword, {said!r} "
                "by config; use AeroMagCompensation-v0 with config, or leave one out"
            )
        self.config = env_config(config, **overrides)
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be None or 'rgb_array', got {render_mode!r}")
        self.render_mode = render_mode
        self._action_size = action_size(self.config)
        self.action_space = spaces.Box(-1.0, 1.0, (self._action_size,), np.float32)
        self._settings = step_settings(self.config)
        self._shared = packed(self._settings)
        low, high = self._settings.low, self._settings.high
        self.observation_space = spaces.Box(low, high, low.shape, np.float32)
        self._scenario = self.config.scenario
        self._out = np.zeros(len(OUT))

    def reset(
        self, *, seed: int | None = None, options: dict | None = None
    ) -> tuple[np.ndarray, dict]:
        options = reset_options(options, (*RESET_OPTIONS, "filter_method"))
        super().reset(seed=seed)
        if "scenario" in options:
            self._scenario = options["scenario"]
        self._flight_seed = int(self.np_random.integers(2**31))
        self.episode: Episode = make_episode(
            self._scenario, self._flight_seed, self.config.duration_s
        )
        ep = self.episode
        cfg = ep.filter_cfg
        if "filter_method" in options:  # FilterConfig refuses an unknown method in one line
            cfg = replace(cfg, method=options["filter_method"])
        self.filter = FilterState(cfg, ep.y, ep.t_b, ep.tdot_b, store_states=False)
        self._truth = np.ascontiguousarray(ep.truth_interf)
        self._run = np.zeros(N_RUN)
        self._score_start = int(self.config.score_from * ep.n)
        self._rewards: list[float] = []
        return np.zeros(self._settings.low.size, np.float32), {"flight_seed": self._flight_seed}

    @property
    def scenario(self) -> str:
        """The scenario of the current (or next) episode."""
        return self._scenario

    @property
    def log_scales(self) -> tuple[float, float]:
        """Natural logs of the cumulative Q and R scales relative to their initial values."""
        return float(self._run[RUN.log_q]), float(self._run[RUN.log_r])

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict]:
        a = check_actions(action, size=self._action_size)
        f, obs, out = self.filter, np.empty(self._settings.low.size, np.float32), self._out
        arrays = packed(EnvArrays(a, self._run, self._truth, obs, out))
        kernels.env_step(int(f.mode), f.n, self._score_start, arrays, self._shared, f.packed())
        reward = float(out[OUT.reward])
        terminated, truncated = bool(out[OUT.terminated]), bool(out[OUT.truncated])
        self._rewards.append(reward)
        return obs, reward, terminated, truncated, self._info()

    def _info(self) -> dict[str, Any]:
        return info(self._out, self.filter.ints, self._flight_seed)

    def render(self) -> np.ndarray | None:
        if self.render_mode != "rgb_array":
            return None
        from aeromag_env.environment.render import render_episode

        return render_episode(self)
