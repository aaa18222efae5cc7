"""The PPO design study behind the README: which observation/action design can learn, and how
much room the scenario leaves (numbers on validation seeds 50 000–50 019, one run each).

``python experiments/ppo_design_study.py trial --steps 1000000 --s-max 10 --action-mode relative``
trains PPO (hyperparameters of ``agents/training/hyperparams/ppo.json``) with the given action
design on ``nonstationary`` and prints its validation RMSE next to ``fis`` and ``tuned_constant``.
``--paper-obs`` uses the paper's two observations only (without the Q and R scales, whiteness,
progress and recent ROR after them); ``--split-q`` makes T_p's Q a third action.

``python experiments/ppo_design_study.py headroom`` runs privileged schedules (true noise
variance for R, Q raised for a few seconds after each true interference step): what a tuner that
knew everything could reach, i.e. the ceiling for any learned tuner in this scenario. With the
whole Q raised (the paper's single Q action) and then with only T_p's Q raised (a T_p action),
also with the raise delayed by 1 and 3 s (a detector that needs time) and with a constant R.

``python experiments/ppo_design_study.py detector [--test N]`` runs hand-written causal detectors:
T_p's Q raised once a statistic of the innovations exceeds a threshold, Q(0) otherwise, R at
100 × R(0) — the privileged split schedule with the true step times replaced by what the
innovations show. Statistics: the ``log_step_statistic`` observation and the norm of the mean
innovation over the last decision window (``log_mean_innovation_power``); ``--test N`` runs on
the first
N test flights instead of the validation flights.

``python experiments/ppo_design_study.py shift [--policy PATH] [--episodes 40]`` runs a learned
policy, the 20 nT mean-innovation rule and their two hybrids (the policy's T_p action with the
rule's Q and R, and the reverse) on the evaluated scenario and on the training scenario
``nonstationary_dense``.

Every step prints; only ``trial`` writes (its policy, ``--out``, default
``results/ppo_trial.npz``). ``--quick`` on every step: 2 flights (and for ``trial`` a
test-sized training, :data:`agents.training.quick.QUICK`).
"""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

if __package__ in (None, ""):  # run by its path, from anywhere: this checkout's packages first
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import aeromag_env  # noqa: F401
from aeromag_env.environment.config import env_config
from aeromag_env.environment.observations import PAPER_OBSERVATIONS
from aeromag_env.environment.spaces import BASE_ACTIONS, observation_index
from aeromag_env.quick import add_quick_option
from aeromag_env.simulation.interference import STATE_SLICES
from agents.evaluation.episodes import run_episode
from agents.evaluation.seeds import TEST_SEED_START, VALIDATION_SEEDS
from agents.policies import DEFAULT_PPO, make_policy
from agents.training.quick import QUICK

SEEDS = range(VALIDATION_SEEDS.start, VALIDATION_SEEDS.start + 20)


class PrivilegedSchedule:
    """R = true noise variance × 10^r_off; Q = 10^q_high for ``hold_s`` after each step, else
    10^q_low (absolute action mode)."""

    def __init__(self, env: Any, q_low: float, q_high: float, hold_s: float, r_off: float) -> None:
        self.env = env.unwrapped
        self.q_low, self.q_high, self.hold_s, self.r_off = q_low, q_high, hold_s, r_off

    def predict(
        self, obs: Any, state: Any = None, episode_start: Any = None, deterministic: bool = True
    ) -> tuple[np.ndarray, Any]:
        e = self.env
        k = min(e.filter.k, e.episode.n - 1)
        jumps = np.abs(np.diff(e.episode.truth_interf, axis=0)).max(axis=1) > 5.0
        steps = np.flatnonzero(jumps) + 1
        recent = np.any((k - steps >= 0) & (k - steps < self.hold_s * 10))
        log_q = self.q_high if recent else self.q_low
        log_r = (
            math.log10(e.episode.noise_var[k] / float(np.mean(np.diag(e.filter.r0)))) + self.r_off
        )
        (q_lo, q_hi), (r_lo, r_hi) = e.config.action.q_log10, e.config.action.r_log10
        a = [2 * (log_q - q_lo) / (q_hi - q_lo) - 1, 2 * (log_r - r_lo) / (r_hi - r_lo) - 1]
        return np.clip(np.array(a, np.float32), -1, 1), state


def _mean_rmse(env: Any, policy: Any, seeds: Sequence[int] = SEEDS) -> float:
    return float(np.mean([run_episode(env, policy, s)["rmse_nt"] for s in seeds]))


def headroom(seeds: Sequence[int] = SEEDS) -> None:
    env = gym.make(
        "AeroMagCompensation-v0",
        scenario="nonstationary",
        observations=_observations(),
        action={"mode": "absolute"},
    )
    base = gym.make("AeroMagCompensation-v0", scenario="nonstationary")
    print(f"fis {_mean_rmse(base, make_policy('fis', base), seeds):.3f} nT")
    for args in [(-10, 4, 30, 0), (-10, 8, 10, 0), (-10, 9, 5, 0), (-10, 8, 10, -1)]:
        rmse = _mean_rmse(env, PrivilegedSchedule(env, *args), seeds)
        print(f"privileged {args}: {rmse:.3f} nT")
    episodes = []
    for seed in seeds:
        base.reset(seed=seed)
        episodes.append(base.unwrapped.episode)
    for kw in [{}, {"delay_s": 1.0}, {"delay_s": 3.0}, {"r_log10": 2.0}]:
        rmse = np.mean([privileged_split(ep, **kw) for ep in episodes])
        print(f"privileged, T_p's Q only, 10^10 for 3 s, {kw or 'R true'}: {rmse:.3f} nT")


def privileged_split(
    episode: Any, delay_s: float = 0.0, r_log10: float | None = None, window: int = 10
) -> float:
    """RMSE (second half) of the filter with T_p's Q at 10^10 × Q(0) for 3 s after each true
    step (``delay_s`` late) and the other 18 states' Q at Q(0); R the true noise variance, or
    ``10^r_log10`` × R(0)."""
    from aeromag_env.compensation.kalman import FilterState

    ep = episode
    f = FilterState(ep.filter_cfg, ep.y, ep.t_b, ep.tdot_b, store_states=False)
    jumps = np.abs(np.diff(ep.truth_interf, axis=0)).max(axis=1) > 5.0
    steps = np.flatnonzero(jumps) + 1 + round(delay_s * 10)
    r0 = f.rm.copy()
    for k in range(0, ep.n, window):
        scale = np.ones(f.qd.size)
        if np.any((k - steps >= 0) & (k - steps < 30)):
            scale[STATE_SLICES["permanent"]] = 1e10
        f.qd[:] = f.q0 * scale
        f.rm[:] = np.eye(3) * ep.noise_var[k] if r_log10 is None else r0 * 10**r_log10
        f.advance(k + window)
    err = (f.est - ep.truth_interf)[ep.n // 2 :]
    return float(np.sqrt(np.mean(err**2)))


#: Absolute-action ranges of the detector schedules (ppo.json's since version 2).
RANGES = {"q_log10": (-4.0, 4.0), "r_log10": (-1.0, 3.0), "qp_log10": (-2.0, 10.0)}
#: The detector schedules' action mapping: absolute actions, T_p's Q a third action.
DETECTOR_ACTION = {"mode": "absolute", "permanent": "graded", **RANGES}
#: The two innovation powers (the last window's |r|² and |mean r|²).
POWERS = ("log_innovation_power", "log_mean_innovation_power")


def _observations(*more: str) -> tuple[str, ...]:
    """The paper's two observations, the current Q and R scales, whiteness, progress and the
    recent ROR, then ``more``."""
    scales = ("log_q_scale", "log_r_scale", "whiteness", "progress", "log_recent_ror")
    return (*PAPER_OBSERVATIONS, *scales, *more)


def _detector_env(*more: str, **action: Any) -> dict[str, Any]:
    """The detector schedules' environment: T_p's Q scale and ``more`` observed, the action
    mapping :data:`DETECTOR_ACTION` (``action`` on top)."""
    return {
        "observations": _observations("log_qp_scale", *more),
        "action": {**DETECTOR_ACTION, **action},
    }


def _absolute_action(log_q: float, log_r: float, log_qp: np.ndarray) -> np.ndarray:
    """The actions (N, 3) that set the scales log10 Q, R, T_p's Q within :data:`RANGES`."""
    (q_lo, q_hi), (r_lo, r_hi), (p_lo, p_hi) = RANGES.values()
    a = [
        2 * (log_q - q_lo) / (q_hi - q_lo) - 1,
        2 * (log_r - r_lo) / (r_hi - r_lo) - 1,
        2 * (log_qp - p_lo) / (p_hi - p_lo) - 1,
    ]
    return np.stack([np.broadcast_to(v, log_qp.shape) for v in a], 1).astype(np.float32)


def _run_batched(cfg: dict[str, Any], seeds: Sequence[int], act: Any) -> float:
    """Mean episode RMSE of ``act(obs (N, n_obs)) → actions`` over ``seeds``, one vector env."""
    from aeromag_env.environment.vec_env import AeroMagCompensationVecEnv

    n = len(seeds)
    env = AeroMagCompensationVecEnv(n, cfg)
    obs, _ = env.reset(seed=list(seeds))
    done, rmse = np.zeros(n, bool), np.full(n, np.nan)
    while not done.all():
        obs, _, terminated, truncated, info = env.step(act(obs))
        ended = (terminated | truncated) & ~done
        if ended.any():
            rmse[ended] = info["episode_rmse_nt"][ended]
        done |= terminated | truncated
    env.close()
    return float(np.mean(rmse))


def _mean_innovation_rule(nt: float, r0: float) -> Any:
    """T_p's Q at 10^10 × Q(0) for the next window when the mean innovation over the last one
    exceeds ``nt`` (the observation ``log_mean_innovation_power``:
    log10 |mean r|² / tr R(0), tr R(0) = 3 ``r0``), else Q(0); R at 100 × R(0)."""
    threshold = math.log10(nt**2 / (3 * r0))
    layout = env_config(**_detector_env(*POWERS))
    col = observation_index(layout, "log_mean_innovation_power")
    return lambda obs: _absolute_action(0.0, 2.0, np.where(obs[:, col] > threshold, 10.0, 0.0))


def detector(seeds: Sequence[int] = SEEDS) -> None:
    """The privileged split schedule's actions, triggered by what the innovations show instead
    of the true step times (a T_p action, absolute actions; one batched run over ``seeds`` per
    threshold): T_p's Q at 10^10 × Q(0) for the next decision window(s), else Q(0); R at
    100 × R(0).

    Two statistics: the two-window change statistic (``log_step_statistic``, held for 3
    windows, the environment's default T_p limit 10^8) and the norm of the mean innovation over
    the last decision window in nT (``log_mean_innovation_power``, ``action.scale_limit`` 1e10,
    held for one window)."""
    from aeromag_env.environment.scenarios import make_episode

    base = {"scenario": "nonstationary"}
    r0 = make_episode("nonstationary", seeds[0]).filter_cfg.r_std_nt ** 2  # per axis [nT²]
    step = {**base, **_detector_env("log_step_statistic")}
    col = observation_index(env_config(**step), "log_step_statistic")

    def held(log_threshold: float, hold_windows: int) -> Any:
        hold = np.zeros(len(seeds), int)

        def act(obs: np.ndarray) -> np.ndarray:
            nonlocal hold
            hold = np.where(obs[:, col] > log_threshold, hold_windows, np.maximum(hold - 1, 0))
            return _absolute_action(0.0, 2.0, np.where(hold > 0, 10.0, 0.0))

        return act

    for threshold in (0.5, 1.0, 1.5, 2.0):  # log10 of the statistic (about 0.1 without a change)
        rmse = _run_batched(step, seeds, held(threshold, 3))
        print(f"detector, log10 change statistic > {threshold}: {rmse:.3f} nT")
    for nt in (15.0, 20.0, 25.0):
        rmse = _run_batched(
            {**base, **_detector_env(*POWERS, scale_limit=1e10)},
            seeds,
            _mean_innovation_rule(nt, r0),
        )
        print(f"detector, |mean innovation| over the last window > {nt:g} nT: {rmse:.3f} nT")
    rmse = _run_batched({**base, **_detector_env(*POWERS)}, seeds, _mean_innovation_rule(20.0, r0))
    print(f"detector, |mean innovation| > 20 nT, T_p's Q at the default limit 10^8: {rmse:.3f} nT")


def shift(policy_path: str, seeds: Sequence[int]) -> None:
    """The learned policy against the 20 nT mean-innovation rule on the evaluated scenario
    (``nonstationary``) and on the training scenario (``nonstationary_dense``), and the two
    hybrids: the policy's T_p action with the rule's constant Q and R, and the rule's T_p action
    with the policy's Q and R. Which part of the policy costs, and whether it is tuned to the
    flights it was trained on."""
    from aeromag_env.environment.scenarios import make_episode

    policy = make_policy(f"ppo:{policy_path}", None)
    r0 = make_episode("nonstationary", seeds[0]).filter_cfg.r_std_nt ** 2
    rule = _mean_innovation_rule(20.0, r0)

    def learned(obs: np.ndarray) -> np.ndarray:
        return np.asarray(policy.predict(obs, deterministic=True)[0], np.float32)

    def mixed(obs: np.ndarray, tp_from_policy: bool) -> np.ndarray:
        a, b = learned(obs), rule(obs)
        q_r, tp = slice(0, len(BASE_ACTIONS)), slice(len(BASE_ACTIONS), None)  # a_q, a_r | a_qp
        return np.concatenate([b[:, q_r], a[:, tp]] if tp_from_policy else [a[:, q_r], b[:, tp]], 1)

    for scenario in ("nonstationary", "nonstationary_dense"):
        cfg = {**policy.env_kwargs, "scenario": scenario}
        rows = {
            "20 nT rule": rule,
            "policy": learned,
            "policy's T_p, rule's Q and R": lambda o: mixed(o, True),
            "rule's T_p, policy's Q and R": lambda o: mixed(o, False),
        }
        for name, act in rows.items():
            print(f"{scenario}, {name}: {_run_batched(cfg, seeds, act):.3f} nT", flush=True)


def trial(
    steps: int,
    s_max: float,
    action_mode: str,
    paper_obs: bool,
    split_q: bool,
    out: Path,
    quick: bool = False,
) -> None:
    import torch
    from stable_baselines3 import PPO

    torch.set_num_threads(1)  # tiny networks: extra threads only contend

    from agents.policies.numpy_policy import NumpyPPOPolicy
    from agents.training.ppo import _ppo_kwargs, export_policy, load_hyperparams, make_training_env
    from agents.training.quick import quick_hyperparams

    hp = load_hyperparams("nonstationary")
    seeds = SEEDS[: QUICK.episodes] if quick else SEEDS
    if quick:
        hp = quick_hyperparams(hp)
    layout = PAPER_OBSERVATIONS if paper_obs else _observations(*(("log_qp_scale",) * split_q))
    env_kwargs = {
        "observations": layout,
        "action": {
            "s_max": s_max,
            "mode": action_mode,
            "permanent": "graded" if split_q else "joint",
        },
    }
    hp = hp.with_values(env_kwargs=env_kwargs)
    venv = make_training_env("nonstationary", hp, seed=0)
    model = PPO("MlpPolicy", venv, seed=0, device="cpu", **_ppo_kwargs(hp))
    model.learn(steps)
    path = export_policy(model, venv, out, {"env_kwargs": env_kwargs})
    policy = NumpyPPOPolicy.load(path)
    env = gym.make("AeroMagCompensation-v0", scenario="nonstationary", **env_kwargs)
    base = gym.make("AeroMagCompensation-v0", scenario="nonstationary")
    fis = _mean_rmse(base, make_policy("fis", base), seeds)
    tuned = _mean_rmse(base, make_policy("tuned_constant", base), seeds)
    learned = _mean_rmse(env, policy, seeds)
    print(f"ppo {learned:.3f} nT; fis {fis:.3f}; tuned_constant {tuned:.3f}; wrote {path}")


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    sub = parser.add_subparsers(dest="cmd", required=True)
    t = sub.add_parser("trial", help="train PPO with one design, fly it beside the baselines")
    t.add_argument("--steps", type=int, default=1_000_000, help="environment steps")
    t.add_argument("--s-max", type=float, default=2.0)
    t.add_argument("--action-mode", default="relative", choices=("relative", "absolute"))
    t.add_argument("--paper-obs", action="store_true", help="the paper's two observations only")
    t.add_argument("--split-q", action="store_true", help="T_p's Q as a third action")
    t.add_argument(
        "--out", type=Path, default=Path("results/ppo_trial.npz"), help="the exported policy"
    )
    sub.add_parser("headroom", help="privileged schedules: the ceiling")
    d = sub.add_parser("detector", help="hand-written causal step detectors")
    d.add_argument(
        "--test",
        type=int,
        default=0,
        metavar="N",
        help="run on the first N test seeds instead of the 20 validation seeds",
    )
    h = sub.add_parser("shift", help="a learned policy against the 20 nT rule, and hybrids")
    h.add_argument("--policy", default=str(DEFAULT_PPO), help="an exported policy (.npz)")
    h.add_argument("--episodes", type=int, default=40, help="validation flights")
    for p in (t, d, h, sub.choices["headroom"]):
        add_quick_option(p, "2 flights (and a tiny training)")
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    flights = QUICK.episodes if args.quick else None
    if args.cmd == "shift":
        n = flights or args.episodes
        shift(args.policy, range(VALIDATION_SEEDS.start, VALIDATION_SEEDS.start + n))
    elif args.cmd == "headroom":
        headroom(SEEDS[:flights])
    elif args.cmd == "detector":
        n = flights or args.test
        detector(range(TEST_SEED_START, TEST_SEED_START + n) if args.test else SEEDS[:flights])
    else:
        steps = QUICK.train_timesteps if args.quick else args.steps
        split = (args.s_max, args.action_mode, args.paper_obs, args.split_q)
        trial(steps, *split, args.out, quick=args.quick)
    return 0


if __name__ == "__main__":
    sys.exit(main())
