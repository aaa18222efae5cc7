"""The Gymnasium environment ``AeroMagCompensation-v0``: tune the compensator's Q and R online."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from aeromag_env.compensation.arrays import packed
from aeromag_env.compensation.kalman import FilterState
from aeromag_env.configs import from_dict, to_dict
from aeromag_env.environment import kernels
from aeromag_env.environment.checks import RESET_OPTIONS, check_config, reset_options
from aeromag_env.environment.kernels import (
    N_PAR,
    OUT_EPISODE_RMSE,
    OUT_Q_SCALE,
    OUT_QOQ,
    OUT_QP_SCALE,
    OUT_R_SCALE,
    OUT_REWARD,
    OUT_RMSE,
    OUT_ROR,
    OUT_TERMINATED,
    OUT_TRUNCATED,
    PAR_ABSOLUTE,
    PAR_K,
    PAR_LN10,
    PAR_LOG_LIMIT,
    PAR_LOG_S_MAX,
    PAR_PENALTY,
    PAR_Q_HI,
    PAR_Q_LO,
    PAR_QP_GATE,
    PAR_QP_HI,
    PAR_QP_LO,
    PAR_R_HI,
    PAR_R_LO,
    PAR_RECENT,
    PAR_REWARD_FORM,
    PAR_REWARD_NT,
    PAR_SPLIT_Q,
    REWARD_FORMS,
    RUN_LOG_Q,
    RUN_LOG_R,
    EnvArrays,
    EnvSettings,
)
from aeromag_env.environment.scenarios import Episode, make_episode
from aeromag_env.environment.spaces import (
    action_size,
    check_actions,
    observation_bounds,
    observation_positions,
)
from aeromag_env.errors import ConfigError


@dataclass(frozen=True, kw_only=True)
class EnvConfig:
    """Environment settings (hyperparameters of a tuner live elsewhere).

    Every field is checked when the configuration is made
    (:func:`aeromag_env.environment.checks.check_config`: a one-line ConfigError naming the
    field, its range and unit); the ranges below are its.

    Attributes
    ----------
    scenario : one of :data:`aeromag_env.environment.scenarios.SCENARIOS`
    decision_window : K, samples the filter advances per step, an integer in [1, 10^6]
    recent_samples : samples of the "last decision window" statistics (the recent ROR, the mean
        innovation power and the two-window change statistic), an integer in [1, 10^6]; None:
        K. A short decision window follows fast noise, a statistic over 5 samples finds no step
    s_max : largest scale factor per step (finite, > 1); action ``a`` → ``s = s_max ** a``
    extras : add log Q scale, log R scale, innovation whiteness and progress to the observation
    reward_scale_nt : error scale of the reward, in [1e-3, 1e6] [nT]
    reward_form : ``log`` (``−ln(1 + e_w/scale)``, the default), ``linear`` (``−e_w/scale``) or
        ``squared`` (``−(e_w/scale)²``; the sum over a flight is its mean squared error, the
        square of the RMSE the tuners are scored by, where ``log`` discounts the large errors
        after an interference step) — a design switch beyond the paper
    divergence_penalty : reward of the step on which the filter diverges, in [-1e6, 0]
    score_from : fraction of the flight after which ``episode_rmse_nt`` is accumulated, in
        [0, 1)
    scale_limit : the cumulative Q and R scales stay within [1/limit, limit] of their initial
        values, limit in (1, 1e100]
    duration_s : override of the scenario's flight length, in [1, 86 400] [s] (None: the
        scenario's)
    action_mode : ``relative`` (the paper's eq. 21: each action multiplies Q and R by
        ``s_max ** a``) or ``absolute`` (the action sets the scales directly:
        ``log10(Q / Q(0)) = lo + (a + 1)/2 · (hi − lo)`` within ``absolute_q_log10``, likewise R
        within ``absolute_r_log10``) — a learning aid: a constant tuning is a constant action
    absolute_q_log10, absolute_r_log10 : (lo, hi) ranges of the absolute mode, lo < hi, each
        in [-100, 100] [decades]
    absolute_qp_log10 : (lo, hi) range of the T_p block's Q in the absolute mode with ``split_q``
    split_q : a third action scales the Q of the permanent-field block T_p (3 states) on its own,
        mapped like ``a_q``, which then scales the induced and eddy blocks (18 states) only — a
        design switch beyond the paper: an interference step (equipment switching on) moves
        T_p, and raising the whole Q to follow it also unsettles the 18 coefficients
    innovation_power : with ``extras``, two more observations, each log10 of a power over
        ``tr R(0)``: the mean innovation power ``mean |r|²`` over the statistics window (the
        noise level) and the power of the mean innovation ``|mean r|²`` over the last decision
        window (a step: noise averages out of it, a step does not); neither depends on R
    qp_gate : with ``split_q`` and ``action_mode="absolute"``, the T_p action is a switch:
        ``a_qp > 0`` sets T_p's Q to the top of ``absolute_qp_log10``, otherwise to the bottom
        — a design switch beyond the paper: the best hand-written step response (raise T_p's
        Q to 10^10 for one window when the mean innovation is large, Q(0) otherwise) is all or
        nothing, and a graded response learned on flights with many steps over-reacts on
        flights with few
    step_statistic : with ``extras``, one more observation: log10 of a two-window change
        statistic, the mean innovation over the last decision window against that over the
        rest of the statistics window, over the latter's innovation variance (about 0 without
        a change at any noise level; an interference step of a few noise std lifts it by
        decades within one window)
    turn_rate : with ``extras``, one more observation: log10 of the RMS of ``|Ṫ| / |T|`` over
        the last decision window [rad/s], the aircraft's angular rate across the Earth field
        from the attitude the filter already reads (−8 without a turn) — a design switch beyond
        the paper: noise that airframe flex and control-surface currents add grows with the
        angular rate, and an innovation burst while turning is that noise, not a step
    innovation_bias : with ``extras``, one more observation: log10 of ``M |mean r|² / tr C``,
        the mean innovation over the statistics window against zero over the innovations'
        covariance trace (about 0 for a consistent filter at any noise level or R) — a step the
        filter missed keeps it high after the two-window statistic has fallen
    """

    scenario: str = "nominal"
    decision_window: int = 10
    recent_samples: int | None = None
    s_max: float = 2.0
    extras: bool = False
    reward_scale_nt: float = 1.0
    reward_form: str = "log"
    divergence_penalty: float = -10.0
    score_from: float = 0.5
    scale_limit: float = 1e8
    duration_s: float | None = None
    action_mode: str = "relative"
    absolute_q_log10: tuple[float, ...] = (-10.0, 10.0)
    absolute_r_log10: tuple[float, ...] = (-3.0, 3.0)
    absolute_qp_log10: tuple[float, ...] = (-10.0, 10.0)
    split_q: bool = False
    innovation_power: bool = False
    step_statistic: bool = False
    turn_rate: bool = False
    innovation_bias: bool = False
    qp_gate: bool = False

    def __post_init__(self) -> None:
        check_config(self)


def parameters(config: EnvConfig) -> np.ndarray:
    """The settings of ``config`` the compiled step reads, as a float vector (N_PAR,) laid out by
    the ``PAR_*`` indices of :mod:`aeromag_env.environment.kernels`."""
    par = np.zeros(N_PAR)
    par[PAR_K] = config.decision_window
    par[PAR_RECENT] = config.recent_samples or config.decision_window
    par[PAR_LOG_S_MAX] = math.log(config.s_max)
    par[PAR_LOG_LIMIT] = math.log(config.scale_limit)
    par[PAR_ABSOLUTE] = float(config.action_mode == "absolute")
    par[PAR_Q_LO], par[PAR_Q_HI] = config.absolute_q_log10
    par[PAR_R_LO], par[PAR_R_HI] = config.absolute_r_log10
    par[PAR_REWARD_NT] = config.reward_scale_nt
    par[PAR_PENALTY] = config.divergence_penalty
    par[PAR_LN10] = math.log(10.0)
    par[PAR_SPLIT_Q] = float(config.split_q)
    par[PAR_QP_LO], par[PAR_QP_HI] = config.absolute_qp_log10
    par[PAR_REWARD_FORM] = REWARD_FORMS.index(config.reward_form)
    par[PAR_QP_GATE] = float(config.qp_gate)
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
    (:class:`agents.policies.FisPolicy`); others are learned. The step is compiled
    (:func:`aeromag_env.environment.kernels.env_step`) and is the same code that
    ``gym.make_vec("AeroMagCompensation-v0", num_envs=N)`` runs for N environments at once
    (:class:`aeromag_env.environment.vec_env.AeroMagCompensationVecEnv`).

    ## Action Space

    ``Box(-1, 1, (2,), float32)``: ``[a_q, a_r]`` → ``s_a = s_max ** a_q``, ``s_r = s_max ** a_r``
    (log scale; ``s_max = 2`` by default, so one step at most doubles or halves Q or R). Values
    outside [-1, 1] are clipped; a non-finite action, or one that is not real numbers (complex,
    bool, text, objects), raises ``ValueError``. The cumulative scales
    are kept within ``[1/scale_limit, scale_limit]`` of the initial Q and R. With
    ``action_mode="absolute"`` an action sets the log scale within a fixed range instead. With
    ``split_q=True`` the space is ``(3,)``: ``[a_q, a_r, a_qp]``, where ``a_qp`` scales the Q of
    the permanent-field states T_p and ``a_q`` that of the other 18; with ``qp_gate=True``
    only the sign of ``a_qp`` counts (T_p's Q at the top or the bottom of its range).

    ## Observation Space

    ``Box(-8, 8, (2,), float32)`` — the paper's inputs at the end of the window:

    | index | observation | meaning |
    |---|---|---|
    | 0 | log10 ROR | windowed innovation trace over its predicted trace (eq. 22), 0 before data |
    | 1 | log10 QOQ | ``tr(K C_r Kᵀ) / tr Q`` (covariance matching), 0 before data |

    With ``extras=True`` five more: log10 of the cumulative Q scale and R scale, the lag-1
    autocorrelation of the innovations over the last window (whiteness, in [-1, 1]), the
    progress through the flight (in [0, 1]) and log10 of the ROR over the last decision window
    only (it reacts to an interference step within K samples, the M-window ROR only slowly);
    with ``split_q`` an eighth, log10 of the cumulative T_p Q scale; with ``innovation_power``
    two more, with ``step_statistic``, ``turn_rate`` and ``innovation_bias`` one more each, in
    that order (see :class:`EnvConfig`). Their names and columns:
    :func:`aeromag_env.environment.spaces.observation_names` and
    :func:`~aeromag_env.environment.spaces.observation_index` (actions:
    :data:`~aeromag_env.environment.spaces.ACTIONS`).

    ## Rewards

    ``r = −ln(1 + e_w / reward_scale_nt)`` with ``e_w`` the RMS over the window of the true
    interference minus the filter's a-priori estimate (pooled over axes) [nT]; ``reward_form``
    ``linear`` gives ``−e_w / reward_scale_nt`` and ``squared`` ``−(e_w / reward_scale_nt)²``.
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

    ``gym.make("AeroMagCompensation-v0", config=EnvConfig(...) or dict, render_mode=None |
    "rgb_array")``; keyword shortcuts: ``scenario=``, ``decision_window=``, ``extras=``.
    ``info`` holds ``rmse_window_nt``, ``ror``, ``qoq``, ``q_scale``, ``r_scale``,
    ``q_permanent_scale`` (1 unless ``split_q``), ``sample``,
    ``flight_seed``, and the episode's totals so far — at every step, so that the step on which
    a ``TimeLimit`` (``gym.make(..., max_episode_steps=N)``) cuts the episode carries them:
    ``episode_rmse_nt`` (over the flight after ``score_from``; over the part flown when the
    episode ends before it), ``divergences`` and ``outliers_rejected`` (samples the filter's
    outlier gate skipped: a spike or a burst of noise in the fluxgate; 0 on a clean flight).

    ## Version History

    * v0: first version.
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 4}  # noqa: RUF012 (gymnasium API)

    def __init__(
        self,
        config: EnvConfig | dict | None = None,
        render_mode: str | None = None,
        **overrides: Any,
    ) -> None:
        base = from_dict(EnvConfig, config) if config is not None else EnvConfig()
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
        self.config = from_dict(EnvConfig, {**to_dict(base), **overrides})
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
        self._out = np.zeros(kernels.N_OUT)

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
        self._run = np.zeros(kernels.N_RUN)
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
        return float(self._run[RUN_LOG_Q]), float(self._run[RUN_LOG_R])

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict]:
        a = check_actions(action, size=self._action_size)
        f, obs, out = self.filter, np.empty(self._settings.low.size, np.float32), self._out
        arrays = packed(EnvArrays(a, self._run, self._truth, obs, out))
        kernels.env_step(int(f.mode), f.n, self._score_start, arrays, self._shared, f.packed())
        reward = float(out[OUT_REWARD])
        terminated, truncated = bool(out[OUT_TERMINATED]), bool(out[OUT_TRUNCATED])
        self._rewards.append(reward)
        return obs, reward, terminated, truncated, self._info()

    def _info(self) -> dict[str, Any]:
        out = self._out
        info = {
            "rmse_window_nt": float(out[OUT_RMSE]),
            "ror": float(out[OUT_ROR]),
            "qoq": float(out[OUT_QOQ]),
            "q_scale": float(out[OUT_Q_SCALE]),
            "r_scale": float(out[OUT_R_SCALE]),
            "q_permanent_scale": float(out[OUT_QP_SCALE]),
            "sample": self.filter.k,
            "flight_seed": self._flight_seed,
            "episode_rmse_nt": float(out[OUT_EPISODE_RMSE]),
            "divergences": self.filter.divergences,
            "outliers_rejected": self.filter.outliers_rejected,
        }
        return info

    def render(self) -> np.ndarray | None:
        if self.render_mode != "rgb_array":
            return None
        from aeromag_env.environment.render import render_episode

        return render_episode(self)
