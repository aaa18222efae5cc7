"""Aircraft aeromagnetic compensation: simulator, compensators, tuning environment.

Importing the package registers the Gymnasium environment ``AeroMagCompensation-v0`` (the
environment module itself is imported only by ``gym.make``).
"""

from gymnasium.envs.registration import register as _register

__version__ = "0.1.0"

_register(id="AeroMagCompensation-v0", entry_point="aeromag_env.env:AeroMagCompensationEnv")
