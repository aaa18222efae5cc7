"""The tuners of the compensator's noise covariances, in four rooms, each importing only the
rooms below it (``tests/test_layout.py`` checks it):

* :mod:`agents.policies` — the policies and the registry from a name to a policy
  (:func:`~agents.policies.make_policy`), the shipped PPO policies and tuned constants;
* :mod:`agents.evaluation` — episodes, every policy on the same test flights, their statistics
  and figures;
* :mod:`agents.training` — PPO and the other learners, imitation warm starts, validation, the
  hyperparameter files and what ``--quick`` means;
* :mod:`agents.search` — the searches: PPO's and the other learners' hyperparameters on Ray Tune
  (:mod:`~agents.search.ppo`, :mod:`~agents.search.learners`, their spaces in
  :mod:`~agents.search.space`) and the grid search of the tuned constant
  (:mod:`~agents.search.tuned_constant`);
* :mod:`agents.comparison` — the learners compared: the statistics of their results pages.

``agents`` imports ``aeromag_env``'s environment and the layers below it; the jobs
(:mod:`aeromag_env.jobs`) import ``agents``. Importing ``agents`` itself loads nothing heavy.

Note: the import name ``agents`` is also used by unrelated PyPI packages; do not install those
into the same environment.
"""
