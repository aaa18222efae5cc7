"""Tuning policies for ``AeroMagCompensation-v0``, all
:class:`agents.policies.protocol.TuningPolicy`.

``predict(obs, state=None, episode_start=None, deterministic=True) -> (action, state)``, so one
evaluation loop serves every policy, learned or not; :class:`BasePolicy` writes it once and
each policy says only how it acts (:meth:`BasePolicy.act`). Actions are ``[a_q, a_r]`` in
[-1, 1]; the environment maps them to scale factors ``s = s_max ** a`` on Q and R.

* ``constant`` — no adaptation (the filter keeps its initial Q and R).
* ``fis`` — the paper's fuzzy rules (§3.4, :mod:`aeromag_env.compensation.fuzzy`, the code the
  ``fakf`` filter uses) on the observed ROR and QOQ, once per statistics window (every M / K
  steps), as ``fakf``.
* ``sage_husa``, ``ding`` — the classical adaptive filters: the environment runs its filter with
  that built-in adaptation (``reset``'s ``filter_method`` option, which these policies name in
  ``BasePolicy.reset_options``; the same compiled code as ``aeromag compensate --method``)
  and they output zero actions.
* ``tuned_constant`` — the best constant Q and R scale found offline on training seeds
  (:mod:`agents.search.tuned_constant`), applied at the start of the episode, then held.
* ``oracle`` — knows the true noise variance (simulation only) and steers R to it.

The policies that know more than the observations (``oracle``, ``privileged``,
``tuned_constant``, the classical ones) read one environment's
:func:`~aeromag_env.environment.truth.flight_truth`, a read-only view: they never change the
environment.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Mapping
from types import MappingProxyType
from typing import Any, ClassVar

import numpy as np

from aeromag_env.compensation.fuzzy import zoomed_scale
from aeromag_env.environment.spaces import (
    ACT_Q,
    ACT_QP,
    ACT_R,
    ACTIONS,
    BASE_ACTIONS,
    OBS_LOG_QOQ,
    OBS_LOG_ROR,
    observation_index,
)
from aeromag_env.environment.truth import FlightTruth, flight_truth
from aeromag_env.errors import ConfigError
from agents.policies.protocol import State
from agents.policies.tuned_table import load_tuned


class BasePolicy(ABC):
    """The :class:`~agents.policies.protocol.TuningPolicy` plumbing of the hand-written policies:
    one observation or a batch in, float32 actions clipped to [-1, 1] out.

    A policy bound to one environment (``single_env``: it reads that environment's truth)
    refuses a batch with a ``ValueError``.
    """

    name: str = ""
    #: Options of the environment's ``reset`` the policy needs (passed by
    #: :func:`agents.evaluation.episodes.run_episode`); none by default.
    reset_options: Mapping[str, Any] = MappingProxyType({})
    #: Whether the policy reads one environment's truth (then it takes one observation).
    single_env: ClassVar[bool] = False

    def predict(
        self,
        obs: np.ndarray,
        state: State = None,
        episode_start: np.ndarray | None = None,
        deterministic: bool = True,
    ) -> tuple[np.ndarray, State]:
        """See :meth:`agents.policies.protocol.TuningPolicy.predict`."""
        batch, single = _batch(obs)
        if self.single_env and not single:
            raise ValueError(
                f"policy {self.name!r} is bound to one environment; it takes one observation"
            )
        actions, state = self.act(batch, state, episode_start)
        return _out(actions, single), state

    @abstractmethod
    def act(
        self, obs: np.ndarray, state: State, episode_start: np.ndarray | None
    ) -> tuple[np.ndarray, State]:
        """Actions (N, n_act), before clipping, for observations ``obs`` (N, n_obs) float64,
        and the state for the next call."""


def _batch(obs: np.ndarray) -> tuple[np.ndarray, bool]:
    obs = np.asarray(obs, dtype=np.float64)
    return (obs[None, :], True) if obs.ndim == 1 else (obs, False)


def _out(actions: np.ndarray, single: bool) -> np.ndarray:
    actions = np.clip(actions, -1.0, 1.0).astype(np.float32)
    return actions[0] if single else actions


class ConstantPolicy(BasePolicy):
    """No adaptation: zero actions."""

    name = "constant"

    def act(
        self, obs: np.ndarray, state: State, episode_start: np.ndarray | None
    ) -> tuple[np.ndarray, State]:
        return np.zeros((obs.shape[0], len(BASE_ACTIONS))), state


class FisPolicy(BasePolicy):
    """The paper's fuzzy rules: ``s_r = FIS(ROR)^b_r``, ``s_a = FIS(QOQ)^b_a`` (eq. 21).

    Parameters
    ----------
    s_max : the environment's largest per-step scale (action ``a`` → ``s_max ** a``)
    interval : steps between adaptations (M / K: once per statistics window, like ``fakf``)
    epsilon, eta, zoom_r, zoom_q : the paper's FIS parameters
    """

    name = "fis"

    def __init__(
        self,
        s_max: float = 2.0,
        interval: int = 5,
        epsilon: float = 0.05,
        eta: float = 0.025,
        zoom_r: float = 1.0,
        zoom_q: float = 1.0,
    ) -> None:
        self.log_s_max = math.log(s_max)
        self.interval, self.eps, self.eta = interval, epsilon, eta
        self.zoom_r, self.zoom_q = zoom_r, zoom_q

    def act(
        self, obs: np.ndarray, state: State, episode_start: np.ndarray | None
    ) -> tuple[np.ndarray, State]:
        steps = _step_counter(state, episode_start, obs.shape[0])
        actions = np.zeros((obs.shape[0], len(BASE_ACTIONS)))
        for i, row in enumerate(obs):
            if steps[i] > 0 and steps[i] % self.interval == 0 and row[OBS_LOG_ROR] != 0.0:
                ror, qoq = 10.0 ** row[OBS_LOG_ROR], 10.0 ** row[OBS_LOG_QOQ]
                s_a = zoomed_scale(qoq, self.eta, self.zoom_q)
                s_r = zoomed_scale(ror, self.eps, self.zoom_r)
                actions[i, ACT_Q] = math.log(s_a) / self.log_s_max
                actions[i, ACT_R] = math.log(s_r) / self.log_s_max
        return actions, steps + 1


def _step_counter(state: State, episode_start: Any, n: int) -> np.ndarray:
    """Steps since the episode started, per environment (kept in the SB3 ``state`` slot)."""
    steps = np.zeros(n, dtype=np.int64) if state is None else np.asarray(state, dtype=np.int64)
    if episode_start is not None:
        steps = np.where(np.asarray(episode_start, bool).reshape(-1), 0, steps)
    return steps


class _Bound(BasePolicy):
    """A policy bound to one environment, whose truth it reads (never changes)."""

    single_env = True

    def __init__(self, env: Any) -> None:
        self._env = env.unwrapped
        self.config = self._env.config  # frozen

    def truth(self) -> FlightTruth:
        """The read-only view of the bound environment's flight and filter."""
        return flight_truth(self._env)


class ClassicalPolicy(_Bound):
    """Sage–Husa or Ding et al. 2007: the filter's own adaptation, which the environment runs
    when reset with this policy's ``reset_options``; zero actions."""

    def __init__(self, method: str, env: Any) -> None:
        super().__init__(env)
        self.name = method.replace("-", "_")
        self.method = method
        self.reset_options = MappingProxyType({"filter_method": method})

    def act(
        self, obs: np.ndarray, state: State, episode_start: np.ndarray | None
    ) -> tuple[np.ndarray, State]:
        if self.truth().filter_method != self.method:
            raise ConfigError(
                f"policy {self.name!r} needs the environment reset with "
                f"options={dict(self.reset_options)} "
                "(agents.evaluation.episodes.run_episode passes them)"
            )
        return np.zeros((1, len(BASE_ACTIONS))), state


class TargetScalePolicy(_Bound):
    """Steer the cumulative log Q and log R scales to targets (within the per-step limit)."""

    name = "target"

    def __init__(self, env: Any, log_q: float = 0.0, log_r: float = 0.0) -> None:
        super().__init__(env)
        self.log_q, self.log_r = log_q, log_r

    def targets(self, truth: FlightTruth) -> tuple[float, float]:
        """The natural logs of the Q and R scales to steer to, given ``truth``."""
        return self.log_q, self.log_r

    def act(
        self, obs: np.ndarray, state: State, episode_start: np.ndarray | None
    ) -> tuple[np.ndarray, State]:
        truth = self.truth()
        log_s_max = math.log(self.config.action.s_max)
        tq, tr = self.targets(truth)
        log_q, log_r = truth.log_scales
        action = np.zeros((1, len(BASE_ACTIONS)))
        action[0, ACT_Q] = (tq - log_q) / log_s_max
        action[0, ACT_R] = (tr - log_r) / log_s_max
        return action, state


class TunedConstantPolicy(TargetScalePolicy):
    """The best constant Q and R scales for the scenario, found offline on training seeds."""

    name = "tuned_constant"

    def __init__(self, env: Any, table: dict[str, dict[str, float]] | None = None) -> None:
        table = table or load_tuned()
        scenario = env.unwrapped.scenario
        if scenario not in table:
            raise ConfigError(
                f"no tuned constants for scenario {scenario!r}; tuned scenarios: "
                f"{', '.join(sorted(table))} (experiments/tune_constants.py in a checkout tunes "
                "more)"
            )
        entry = table[scenario]
        super().__init__(env, math.log(10.0) * entry["log10_q"], math.log(10.0) * entry["log10_r"])


class OraclePolicy(TargetScalePolicy):
    """Knows the true noise variance of the current sample and sets R to it (Q unchanged)."""

    name = "oracle"

    def targets(self, truth: FlightTruth) -> tuple[float, float]:
        k = min(truth.sample, truth.n - 1)
        return 0.0, math.log(truth.noise_var[k] / truth.r0_nt2)


class InnovationDetectorPolicy(BasePolicy):
    """A hand-written step detector (``experiments/ppo_design_study.py detector``): T_p's Q at
    10^10 × Q(0) for the next window when the mean innovation over the last decision window
    exceeds ``threshold_nt``, else at Q(0); the other 18 states' Q at Q(0) and R at 100 × R(0).

    Needs the environment layout it reads and acts in (``config`` an
    :class:`aeromag_env.environment.env.EnvConfig`, e.g. the ``nonstationary`` preset): the
    observation ``log_mean_innovation_power``, absolute actions and a T_p action
    (``action.permanent`` ``graded``, or ``gate``: its T_p action is then ±1).
    ``r0_nt2`` is the filter's initial R per axis [nT²] (the package default, which the
    ``nonstationary`` scenarios use). Not a tuner to table: the demonstrator of PPO's optional
    pretraining (:func:`agents.training.imitation.behaviour_clone`).
    """

    name = "innovation_detector"

    def __init__(
        self,
        config: Any,
        threshold_nt: float = 20.0,
        r0_nt2: float | None = None,
        log_q: float = 0.0,
        log_r: float = 2.0,
        log_qp: float = 10.0,
    ) -> None:
        from aeromag_env.compensation.model import FilterConfig

        act = config.action
        if not (
            "log_mean_innovation_power" in config.observations
            and act.permanent != "joint"
            and act.mode == "absolute"
        ):
            raise ConfigError(
                "innovation_detector needs the observation log_mean_innovation_power, "
                "action.mode='absolute' and a T_p action (action.permanent graded or gate)"
            )
        r0 = FilterConfig().r_std_nt ** 2 if r0_nt2 is None else r0_nt2
        # |mean r|² over the last decision window / tr R(0)
        self.column = observation_index(config, "log_mean_innovation_power")
        self.log_threshold = math.log10(threshold_nt**2 / (3.0 * r0))
        gate = act.permanent == "gate"
        self.quiet = np.zeros(len(ACTIONS))
        self.quiet[ACT_Q] = _to_action(log_q, act.q_log10)
        self.quiet[ACT_R] = _to_action(log_r, act.r_log10)
        self.quiet[ACT_QP] = -1.0 if gate else _to_action(0.0, act.qp_log10)
        self.raise_qp = 1.0 if gate else _to_action(log_qp, act.qp_log10)

    def act(
        self, obs: np.ndarray, state: State, episode_start: np.ndarray | None
    ) -> tuple[np.ndarray, State]:
        actions = np.repeat(self.quiet[None, :], obs.shape[0], axis=0)
        actions[obs[:, self.column] > self.log_threshold, ACT_QP] = self.raise_qp
        return actions, state


class PrivilegedPolicy(_Bound):
    """Knows what no real tuner can: the true noise variance of the coming decision window (R
    set to its largest: a burst that starts within the window is not let in at a small R), the
    Q the truth implies (``Episode.q_log10_true``: the package's well-tuned Q for the induced and
    eddy blocks; for T_p zero, or the drift's variance where the permanent field drifts) and
    when the interference steps (``Episode.step_samples``): T_p's Q at the top of its range for
    the ``after`` decision windows that begin at or follow a step. The upper anchor of the
    normalized score.

    ``cautious_start`` (as the teacher of a policy that sees only observations): R at the top of
    its range in the first window, before any observation — a learner cannot know the noise
    yet, and a first window at too small an R collapses P onto wrong coefficients that a small
    Q never leaves (measured: 63 nT on a ``paper`` flight against the teacher's 1.0).

    ``r_floor`` (as a teacher, ``pretrain.teacher_r_floor``): per scenario, the log10 R scale
    it never sets R below. Foresight makes a small R safe between bursts of equipment noise; a
    tuner that sees a burst a window late has let it in by then, and where the filter tracks a
    drift the error stays for the rest of the burst (one window late, K = 10: 4.24 nT on
    ``noise_bursts`` against the tuned constant's 2.57; with R ≥ 10² R(0) 1.96 —
    ``python -m experiments.lagged_privileged --floors``).

    Acts in the layout of ``ENV_KWARGS`` (absolute actions, a graded T_p action; the paper's
    observations), which :func:`agents.policies.policy_env_kwargs` gives the environment it is
    evaluated in.
    """

    name = "privileged"
    #: The environment layout it acts in.
    ENV_KWARGS: dict[str, Any] = {  # noqa: RUF012 (read-only)
        "action": {
            "mode": "absolute",
            "permanent": "graded",
            "q_log10": (-10.0, 6.0),
            "r_log10": (-2.0, 7.0),
            "qp_log10": (-6.0, 10.0),
            "scale_limit": 1e10,
        }
    }

    def __init__(
        self,
        env: Any,
        after: int = 1,
        cautious_start: bool = False,
        r_floor: Mapping[str, float] | None = None,
    ) -> None:
        super().__init__(env)
        act = self.config.action
        if not (act.permanent != "joint" and act.mode == "absolute"):
            raise ConfigError(
                "privileged needs action.mode='absolute' and a T_p action (action.permanent "
                "graded or gate)"
            )
        self.after, self.cautious_start = after, cautious_start
        self.r_floor = dict(r_floor or {})

    def act(
        self, obs: np.ndarray, state: State, episode_start: np.ndarray | None
    ) -> tuple[np.ndarray, State]:
        truth, act = self.truth(), self.config.action
        k, width = truth.sample, self.config.decision_window
        q_blocks, q_tp = truth.q_log10_true
        action = np.zeros((1, len(ACTIONS)))
        action[0, ACT_Q] = _to_action(q_blocks, act.q_log10)
        action[0, ACT_R] = self.r_action(truth.noise_var[min(k, truth.n - 1) : k + width], truth)
        if self.cautious_start and k == 0:
            action[0, ACT_R] = 1.0
        steps = truth.step_samples
        near = (steps < k + width) & (steps >= k - self.after * width)
        quiet = -1.0 if act.permanent == "gate" else _to_action(q_tp, act.qp_log10)
        action[0, ACT_QP] = 1.0 if near.any() else quiet
        return action, state

    def r_action(self, noise_var: np.ndarray, truth: FlightTruth) -> float:
        """The R action for a window whose true noise variances are ``noise_var``: R at their
        largest, or at the floor of ``r_floor`` for the flight's scenario (``truth``) when that
        is higher."""
        log_r = math.log10(noise_var.max() / truth.r0_nt2)
        floor = self.r_floor.get(truth.scenario, -math.inf)
        return _to_action(max(log_r, floor), self.config.action.r_log10)


def _to_action(log10_scale: float, lo_hi: tuple[float, ...]) -> float:
    """The absolute-mode action that sets ``log10(scale)`` within the range ``(lo, hi)``."""
    lo, hi = lo_hi
    return 2.0 * (log10_scale - lo) / (hi - lo) - 1.0
