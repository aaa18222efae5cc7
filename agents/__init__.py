"""Tuning policies for the compensator's noise covariances (FIS baseline, classical adaptive,
PPO), all with the stable-baselines3 ``predict`` shape. Imports ``aeromag_env``, never the
reverse. The policies arrive with the environment (see DESIGN.md, "Tuning policies").

Note: the import name ``agents`` is also used by unrelated PyPI packages; do not install those
into the same environment.
"""
