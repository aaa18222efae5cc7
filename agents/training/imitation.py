"""Pretraining of PPO by imitation (``pretrain`` in ``agents/training/hyperparams/ppo.json``):
behaviour cloning of the hand-written innovation detector, or DAgger with the privileged policy as
the teacher. Used by :mod:`agents.training.ppo`; torch is imported here only when called.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from aeromag_env.atomic import atomic_path
from aeromag_env.environment.config import env_config
from aeromag_env.errors import AeromagError
from agents.evaluation.seeds import TRAIN_SEEDS
from agents.training.hyperparameters import PPOHyperparams, Pretrain


def seed_stream(rank: int, n_envs: int, offset: int) -> Iterator[int]:
    """Training seeds for environment ``rank`` of ``n_envs``, from ``offset`` (wrapping in the
    training range)."""
    k = offset + rank
    while True:
        yield TRAIN_SEEDS.start + k % TRAIN_SEEDS.stop
        k += n_envs


def behaviour_clone(
    model: Any, venv: Any, hp: PPOHyperparams, scenario: str = "nonstationary", seed: int = 0
) -> Demonstrations:
    """Pretrain ``model``'s actor to imitate a demonstrator and its critic to the discounted
    returns of the demonstrator's rollouts (``hp.pretrain``: ``steps`` environment steps
    of the training environments, ``epochs`` passes of Adam at ``learning_rate`` over them,
    ``demonstrator``: ``innovation_detector`` (the default,
    :class:`agents.policies.baselines.InnovationDetectorPolicy` with ``threshold_nt``) or
    ``privileged``
    (:class:`agents.policies.baselines.PrivilegedPolicy`, which knows the truth: the student learns
    what the teacher does from the observations alone)).

    Why: PPO from scratch settles on a constant random walk for T_p (a local optimum); the
    detector's all-or-nothing response to a rare interference step is a large, coordinated
    departure from it that Gaussian exploration does not find. The demonstrator shows it;
    PPO then trains from there. The observation statistics and the reward scale of
    ``VecNormalize`` are those the rollouts leave behind, as PPO's own rollouts would.

    Returns the demonstrations (all rounds' raw observations and the demonstrated actions), for
    the behaviour-cloning steps that keep PPO near them (:class:`CloningTerm`).
    """
    spec = _pretrain(hp)
    steps = spec.steps
    train_scenario = hp.train_scenario or scenario
    if spec.demonstrator != "privileged":
        parts = [_with_returns(_detector_rollouts(venv, hp, steps), hp)]
        _fit(model, venv, hp, parts)
        scenarios = np.full(parts[0][0].shape[0], train_scenario)
        return Demonstrations.of(parts, [scenarios])
    parts, flown, actor = [], [], None
    for round_ in range(spec.dagger_rounds):
        # each round and training seed flies flights of its own
        offset = TRAIN_SEEDS.stop // 2 + 5_000 * round_ + 1_000 * seed
        rollout = _privileged_rollouts(venv, hp, train_scenario, steps, actor, offset)
        parts.append(_with_returns(rollout[:4], hp))
        flown.append(np.concatenate(rollout[4]))
        _fit(model, venv, hp, parts)
        actor = _student(model, venv)
    return Demonstrations.of(parts, flown)


@dataclass(frozen=True)
class Demonstrations:
    """What the demonstrator did: raw observations (n, n_obs), its actions (n, n_actions) and
    the scenario each sample was flown in (n,; a ``suite`` episode's drawn scenario)."""

    obs: np.ndarray
    actions: np.ndarray
    scenarios: np.ndarray

    @classmethod
    def of(cls, parts: list[tuple], scenarios: list[np.ndarray]) -> Demonstrations:
        return cls(
            np.concatenate([p[0] for p in parts]).astype(np.float32),
            np.concatenate([p[1] for p in parts]).astype(np.float32),
            np.concatenate(scenarios).astype(str),
        )

    def only(self, scenarios: list[str]) -> Demonstrations:
        """The samples flown in one of ``scenarios``."""
        keep = np.isin(self.scenarios, scenarios)
        return Demonstrations(self.obs[keep], self.actions[keep], self.scenarios[keep])

    def save(self, path: Path) -> None:
        with atomic_path(path) as tmp, open(tmp, "wb") as fh:
            np.savez(fh, obs=self.obs, actions=self.actions, scenarios=self.scenarios)

    @classmethod
    def load(cls, path: Path) -> Demonstrations:
        with np.load(path, allow_pickle=False) as data:
            return cls(data["obs"], data["actions"], data["scenarios"])


class CloningTerm:
    """Behaviour cloning kept on during PPO (``pretrain.bc_minibatches``): after each PPO update,
    that many minibatches of Adam (``pretrain.bc_learning_rate``) on the actor's mean toward the
    demonstrated actions, drawn at random from the demonstrations (those flown in
    ``pretrain.bc_scenarios`` when given: PPO alone where the student is weak).

    Why: the student imitating the privileged teacher matches the tuned constant where the
    noise follows the manoeuvres, and PPO's updates, driven by the scenarios with interference
    steps, spend that margin within a few hundred thousand steps. Alternating PPO's update with
    a cloning one is the auxiliary phase of phasic policy gradient with the teacher's labels
    in place of the old policy's: PPO still improves the return, from near the demonstrations.
    """

    def __init__(
        self, model: Any, venv: Any, hp: PPOHyperparams, demos: Demonstrations, seed: int
    ) -> None:
        import torch

        spec = _pretrain(hp)
        if spec.bc_scenarios is not None:
            demos = demos.only(list(spec.bc_scenarios))
        if not demos.obs.shape[0]:
            raise AeromagError(
                f"pretrain.bc_scenarios {list(spec.bc_scenarios or [])}: no "
                "demonstration was flown in these scenarios"
            )
        self.model, self.venv, self.demos = model, venv, demos
        self.minibatches, self.batch = spec.bc_minibatches, hp.batch_size
        policy = model.policy
        actor = [*policy.mlp_extractor.policy_net.parameters(), *policy.action_net.parameters()]
        self.optimiser = torch.optim.Adam(actor, lr=float(spec.bc_learning_rate))
        self.generator = torch.Generator().manual_seed(seed)

    def step(self) -> float:
        """One cloning phase; the mean squared action error of its last minibatch."""
        import torch

        policy, loss = self.model.policy, torch.zeros(())
        n = self.demos.obs.shape[0]
        for _ in range(self.minibatches):
            idx = torch.randint(n, (self.batch,), generator=self.generator).numpy()
            x = torch.as_tensor(self.venv.normalize_obs(self.demos.obs[idx]), dtype=torch.float32)
            latent_pi = policy.mlp_extractor.forward_actor(policy.extract_features(x))
            mean = policy.action_net(latent_pi)
            loss = ((mean - torch.as_tensor(self.demos.actions[idx])) ** 2).mean()
            self.optimiser.zero_grad()
            loss.backward()
            self.optimiser.step()
        return float(loss.detach())


def _pretrain(hp: PPOHyperparams) -> Pretrain:
    """``hp.pretrain``; an error if the hyperparameters have none."""
    if hp.pretrain is None:
        raise AeromagError("behaviour cloning needs the hyperparameters' pretrain")
    return hp.pretrain


def _with_returns(rollout: tuple[list, list, list, list], hp: PPOHyperparams) -> tuple:
    """Observations, actions and the discounted returns of one rollout."""
    raw_obs, actions, rewards, dones = rollout
    returns = _discounted(np.array(rewards), np.array(dones), float(hp.gamma))
    return np.concatenate(raw_obs), np.concatenate(actions), returns.reshape(-1)


def _fit(model: Any, venv: Any, hp: PPOHyperparams, parts: list[tuple]) -> None:
    """Adam on the actor's mean (to the demonstrated actions) and the critic (to the returns)
    over all ``parts`` so far, ``epochs`` passes."""
    import torch

    spec = _pretrain(hp)
    x = torch.as_tensor(
        venv.normalize_obs(np.concatenate([p[0] for p in parts])), dtype=torch.float32
    )
    a = torch.as_tensor(np.concatenate([p[1] for p in parts]), dtype=torch.float32)
    returns = np.concatenate([p[2] for p in parts])
    g = torch.as_tensor(venv.normalize_reward(returns), dtype=torch.float32)
    policy = model.policy
    optimiser = torch.optim.Adam(policy.parameters(), lr=float(spec.learning_rate))
    for _ in range(spec.epochs):
        for idx in torch.randperm(x.shape[0]).split(hp.batch_size):
            latent_pi, latent_vf = policy.mlp_extractor(policy.extract_features(x[idx]))
            mean, value = policy.action_net(latent_pi), policy.value_net(latent_vf).flatten()
            loss = ((mean - a[idx]) ** 2).mean() + 0.5 * ((value - g[idx]) ** 2).mean()
            optimiser.zero_grad()
            loss.backward()
            optimiser.step()


def _student(model: Any, venv: Any) -> Any:
    """The model's deterministic actions on raw observations (normalised as in training)."""

    def act(raw_obs: np.ndarray) -> np.ndarray:
        action, _ = model.policy.predict(venv.normalize_obs(raw_obs), deterministic=True)
        return np.clip(action, -1.0, 1.0)

    return act


def _detector_rollouts(venv: Any, hp: PPOHyperparams, steps: int) -> tuple[list, list, list, list]:
    """Raw observations, actions, rewards and dones of the innovation detector driving the
    training environments ``venv`` for ``steps`` steps (their normalisation statistics are
    updated as PPO's own rollouts would)."""
    from agents.policies.baselines import InnovationDetectorPolicy

    demo = InnovationDetectorPolicy(
        env_config(**hp.env_kwargs), threshold_nt=float(_pretrain(hp).threshold_nt)
    )
    raw_obs, actions, rewards, dones = [], [], [], []
    venv.reset()
    obs = venv.get_original_obs()
    for _ in range(steps // venv.num_envs):
        action = demo.predict(obs)[0]
        raw_obs.append(obs)
        actions.append(action)
        _, _, done, _ = venv.step(action)
        rewards.append(venv.get_original_reward())
        dones.append(done)
        obs = venv.get_original_obs()
    return raw_obs, actions, rewards, dones


def _privileged_rollouts(
    venv: Any,
    hp: PPOHyperparams,
    scenario: str,
    steps: int,
    actor: Any = None,
    offset: int = TRAIN_SEEDS.stop // 2,
) -> tuple[list, list, list, list, list]:
    """The same, and the scenario each step was flown in, from
    :class:`agents.policies.baselines.PrivilegedPolicy`, which reads each environment's
    episode (true noise, true Q, step times): it drives ``n_envs`` single environments of the
    training scenario (training seeds from ``offset``, a stream of their own), and ``venv``'s
    observation and reward statistics are updated with what they saw. The student imitates
    what the teacher does from what the student sees (asymmetric imitation: the observations
    only); the teacher raises T_p's Q for three windows after a step (the student sees a step
    a window late), starts cautiously (see its ``cautious_start``) and keeps R above
    ``pretrain.teacher_r_floor`` where given (see its ``r_floor``). With ``actor`` (a
    function of the raw observations), the flights follow its actions and the teacher only
    labels them (DAgger)."""
    from agents.policies.baselines import PrivilegedPolicy

    n = venv.num_envs
    envs = [
        gym.make("AeroMagCompensation-v0", scenario=scenario, **hp.env_kwargs) for _ in range(n)
    ]
    seeds = [seed_stream(rank, n, offset=offset) for rank in range(n)]
    after = teacher_after(env_config(**hp.env_kwargs).decision_window)
    floor = _pretrain(hp).teacher_r_floor
    teachers = [
        PrivilegedPolicy(env, after=after, cautious_start=True, r_floor=floor) for env in envs
    ]
    obs = np.stack([env.reset(seed=next(seeds[i]))[0] for i, env in enumerate(envs)])
    raw_obs, actions, rewards, dones, flown = [], [], [], [], []
    returns = np.zeros(n)
    for _ in range(steps // n):
        flown.append(np.array([env.get_wrapper_attr("episode").scenario for env in envs]))
        action = np.stack([t.predict(o)[0] for t, o in zip(teachers, obs, strict=True)])
        taken = action if actor is None else actor(obs)
        reward, done, nxt = np.zeros(n), np.zeros(n, bool), obs.copy()
        for i, env in enumerate(envs):
            o, r, term, trunc, _ = env.step(taken[i])
            reward[i], done[i] = r, term or trunc
            nxt[i] = env.reset(seed=next(seeds[i]))[0] if done[i] else o
        raw_obs.append(obs)
        actions.append(action)
        rewards.append(reward)
        dones.append(done)
        venv.obs_rms.update(obs)
        returns = returns * float(hp.gamma) + reward  # as VecNormalize tracks the return
        venv.ret_rms.update(returns)
        returns[done] = 0.0
        obs = nxt
    for env in envs:
        env.close()
    return raw_obs, actions, rewards, dones, flown


#: How long after an interference step the teacher holds T_p's Q at the top [samples]: 3 s at
#: 10 Hz, three decision windows of the default 10 samples.
TEACHER_AFTER_SAMPLES = 30


def teacher_after(decision_window: int) -> int:
    """The teacher's ``after`` in decision windows: :data:`TEACHER_AFTER_SAMPLES` whatever the
    window (three windows at 10 samples, six at 5). Held at three windows, a 5-sample teacher
    let go of a step after 1.5 s — half a second of it before the student could see the step —
    and the students of those runs were 1.3–3 times the tuned constant on ``nonstationary``."""
    return max(1, -(-TEACHER_AFTER_SAMPLES // decision_window))


def _discounted(rewards: np.ndarray, dones: np.ndarray, gamma: float) -> np.ndarray:
    """Discounted returns (T, N) of rewards (T, N), restarting after ``dones`` (the tail of
    the last, unfinished episodes is cut: γ^t makes it negligible for γ ≤ 0.9 beyond a few
    dozen steps)."""
    out, acc = np.zeros_like(rewards, dtype=np.float64), np.zeros(rewards.shape[1])
    for t in range(rewards.shape[0] - 1, -1, -1):
        acc = rewards[t] + gamma * acc * ~dones[t]
        out[t] = acc
    return out
