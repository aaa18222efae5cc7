"""
What a policy sees: the observation over an episode
===================================================

The observation is the filter's consistency statistics at the end of each decision window:
the paper's ROR and QOQ, and any further entries of the observation registry
(:mod:`aeromag_env.environment.observations`) named in ``observations``: here the cumulative Q
and R scales, the innovations' whiteness, the progress through the flight and the recent ROR.
This example runs the paper's rules on one flight of ``AeroMag/Nonstationary-v0`` and plots
every observation, named by the environment's own layout.
"""

# %%
# One episode
# -----------
import gymnasium as gym
import matplotlib.pyplot as plt
import numpy as np

import aeromag_env  # noqa: F401  (registers the ids)
from aeromag_env.environment.spaces import observation_names
from agents.policies import make_policy

env = gym.make(
    "AeroMag/Nonstationary-v0",
    observations=(
        "log_ror",
        "log_qoq",
        "log_q_scale",
        "log_r_scale",
        "whiteness",
        "progress",
        "log_recent_ror",
    ),
)
names = observation_names(env.unwrapped.config)
print(env.observation_space)
print(names)

policy = make_policy("fis", env)
obs, info = env.reset(seed=100_003)
observations, rewards, done = [obs], [], False
while not done:
    action, _ = policy.predict(obs, deterministic=True)
    obs, reward, terminated, truncated, info = env.step(action)
    observations.append(obs)
    rewards.append(reward)
    done = terminated or truncated
steps = np.arange(len(observations))
observations = np.array(observations)
print(f"{len(rewards)} steps, episode RMSE {info['episode_rmse_nt']:.2f} nT")

# %%
# Every observation, and the reward
# ---------------------------------
# The interference steps (equipment switching on) show in the recent ROR within one window.
fig, axes = plt.subplots(len(names) + 1, 1, figsize=(8, 9), sharex=True, layout="constrained")
for ax, name, column in zip(axes, names, observations.T, strict=False):
    ax.plot(steps, column, lw=0.7)
    ax.set_ylabel(name, rotation=0, ha="right", fontsize=8)
axes[-1].plot(steps[1:], rewards, lw=0.7, color="tab:red")
axes[-1].set_ylabel("reward", rotation=0, ha="right", fontsize=8)
for step in env.unwrapped.episode.step_samples // env.unwrapped.config.decision_window:
    for ax in axes:
        ax.axvline(step, color="0.6", lw=0.6, ls="--")
axes[-1].set_xlabel("step (one decision window)")
plt.show()
env.close()
