"""
The environment: the paper's rules against the shipped policy
=============================================================

The filter's noise tuning as a Gymnasium environment: every step a policy scales the process
noise Q and the measurement noise R, and the filter advances one decision window. This example
runs the paper's fuzzy rules (``fis``) and the shipped PPO policy (``ppo``, trained on
``nonstationary``) on the same test flights of ``AeroMag/Nonstationary-v0`` and compares the
compensation error each leaves.
"""

# %%
# One evaluation path for every policy
# ------------------------------------
# Policies have stable-baselines3's ``predict`` shape; ``policy_env_kwargs`` gives the
# environment settings a policy was trained with (the PPO policy reads more observations).
import gymnasium as gym
import matplotlib.pyplot as plt

import aeromag_env  # noqa: F401  (registers the ids)
from agents.evaluation.episodes import run_episode
from agents.evaluation.seeds import TEST_SEED_START
from agents.policies import make_policy, policy_env_kwargs

ENV_ID = "AeroMag/Nonstationary-v0"
SEEDS = [TEST_SEED_START + i for i in range(2)]  # test flights: never seen in training

results = {}
for name in ("fis", "ppo"):
    env = gym.make(ENV_ID, **policy_env_kwargs(name))
    policy = make_policy(name, env)
    results[name] = [run_episode(env, policy, seed)["rmse_nt"] for seed in SEEDS]
    env.close()
    print(f"{name:9s}", " ".join(f"{r:6.2f}" for r in results[name]), "nT")

# %%
# Compensation error per flight
# -----------------------------
# RMSE of the interference estimate against the truth over the second half of each flight.
fig, ax = plt.subplots(figsize=(7, 3.5), layout="constrained")
width = 0.35
for i, (name, rmse) in enumerate(results.items()):
    ax.bar([s - SEEDS[0] + (i - 0.5) * width for s in SEEDS], rmse, width, label=name)
ax.set(xticks=range(len(SEEDS)), xticklabels=[f"seed {s}" for s in SEEDS])
ax.set(ylabel="RMSE [nT]", title=ENV_ID)
ax.legend()
plt.show()
