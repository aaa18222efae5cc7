"""The Gymnasium tuning environment: one flight per episode, Q and R scale factors as actions.

:mod:`.env` (the single environment and its configuration), :mod:`.spaces` (the observation and
action layouts, named once), :mod:`.kernels` (the compiled step shared by all forms),
:mod:`.vec_env` (many environments in one compiled call), :mod:`.sb3` (the stable-baselines3
``VecEnv`` adapter), :mod:`.scenarios` (named flight distributions), :mod:`.prefetch` (flights
simulated ahead in a worker) and :mod:`.render`.
"""
