"""The tuning policies and their registry: one name → one policy, all with the stable-baselines3
``predict`` shape (:class:`~agents.policies.protocol.TuningPolicy`).

``constant``, ``fis`` (the paper's rules), the classical adaptive filters (``sage_husa``,
``ding``), ``tuned_constant``, ``oracle``, ``privileged`` (knows the noise and the steps),
``ppo`` (the shipped numpy export of a stable-baselines3 policy trained on ``nonstationary``)
and ``general`` (one PPO policy trained across the scenario suite, shipped the same way).
:mod:`~agents.policies.baselines` holds the hand-written ones, :mod:`~agents.policies.
numpy_policy` the exported PPO (read by :mod:`~agents.policies.policy_file`), :mod:`~agents.
policies.tuned_table` the stored tuned constants. :func:`make_policy` is the one door from a
name to a policy.
"""

from __future__ import annotations

import copy
from collections.abc import Callable
from pathlib import Path
from typing import Any

from aeromag_env.compensation.model import FilterConfig
from aeromag_env.errors import ConfigError
from agents.policies.protocol import TuningPolicy

POLICIES = (
    "constant",
    "fis",
    "sage_husa",
    "ding",
    "tuned_constant",
    "oracle",
    "privileged",
    "ppo",
    "general",
)
#: The shipped PPO policies: trained on ``nonstationary`` (see experiments/train_ppo.py), and the
#: general one trained across the suite (``aeromag train --scenario suite``).
DEFAULT_PPO = Path(__file__).with_name("trained") / "ppo_nonstationary.npz"
GENERAL_PPO = Path(__file__).with_name("trained") / "ppo_general.npz"
SHIPPED = {"ppo": DEFAULT_PPO, "general": GENERAL_PPO}


def available_policies() -> list[str]:
    """:data:`POLICIES` whose artefacts are present (``ppo`` and ``general`` need their shipped
    policy files)."""
    return [p for p in POLICIES if p not in SHIPPED or SHIPPED[p].exists()]


def policy_env_kwargs(name: str) -> dict[str, Any]:
    """Environment settings a policy needs as ``gym.make`` keywords (PPO: those it was trained
    with, for the shipped policies the name of their preset; ``privileged``: its action layout;
    others: none).

    ``ppo`` is the shipped policy; ``ppo:PATH`` loads an exported ``.npz`` (never a pickle).
    """
    if name in SHIPPED or name.startswith("ppo:"):
        return _load_ppo(name).env_kwargs
    if name == "privileged":
        from agents.policies.baselines import PrivilegedPolicy

        return copy.deepcopy(PrivilegedPolicy.ENV_KWARGS)
    return {}


def _load_ppo(name: str) -> Any:
    from agents.policies.numpy_policy import NumpyPPOPolicy

    return NumpyPPOPolicy.load(SHIPPED[name] if name in SHIPPED else name.split(":", 1)[1])


def make_policy(name: str, env: Any) -> TuningPolicy:
    """The policy ``name`` for environment ``env`` (an ``AeroMagCompensation-v0``, wrapped or
    not; the privileged policies read its truth, none changes it); unknown names give a
    one-line error."""
    from agents.policies import baselines as p

    if name.startswith("ppo:"):
        return _load_ppo(name)
    if name not in POLICIES:
        raise ConfigError(f"unknown policy {name!r}; valid policies: {', '.join(POLICIES)}")
    s_max = env.unwrapped.config.action.s_max
    # the FIS adapts once per statistics window M, as the fakf filter does
    interval = max(1, FilterConfig().window // env.unwrapped.config.decision_window)
    makers: dict[str, Callable[[], TuningPolicy]] = {
        "constant": lambda: p.ConstantPolicy(),
        "fis": lambda: p.FisPolicy(s_max=s_max, interval=interval),
        "sage_husa": lambda: p.ClassicalPolicy("sage-husa", env),
        "ding": lambda: p.ClassicalPolicy("ding", env),
        "tuned_constant": lambda: p.TunedConstantPolicy(env),
        "oracle": lambda: p.OraclePolicy(env),
        "privileged": lambda: p.PrivilegedPolicy(env),
        "ppo": lambda: _load_ppo("ppo"),
        "general": lambda: _load_ppo("general"),
    }
    return makers[name]()
