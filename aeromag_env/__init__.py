"""Aircraft aeromagnetic compensation: simulator, compensators, tuning environment.

Importing the package registers the Gymnasium environment ``AeroMagCompensation-v0`` and its
batched vector form (``gym.make_vec(..., vectorization_mode="vector_entry_point")``); the
environment modules themselves are imported only by ``gym.make`` / ``gym.make_vec``.
"""

from gymnasium.envs.registration import register as _register

__version__ = "0.1.0"

_register(
    id="AeroMagCompensation-v0",
    entry_point="aeromag_env.environment.env:AeroMagCompensationEnv",
    vector_entry_point="aeromag_env.environment.vec_env:AeroMagCompensationVecEnv",
)
