"""The searches: hyperparameters on Ray Tune (PPO: :mod:`~agents.search.ppo`; the other learners:
:mod:`~agents.search.learners`; their spaces, ``spaces/``: :mod:`~agents.search.space`) and the
grid search of the best constant Q and R scales (:mod:`~agents.search.tuned_constant`).
"""
