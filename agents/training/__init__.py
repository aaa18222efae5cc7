"""Training the learned tuners: PPO (:mod:`~agents.training.ppo`) and the other learners
(:mod:`~agents.training.learners`), imitation warm starts, validation and checkpoint selection,
the hyperparameter files (``hyperparams/``) and what ``--quick`` means
(:mod:`~agents.training.quick`).
"""

from __future__ import annotations

from aeromag_env.errors import ArgumentError

#: The learners of the general tuner, in the order of every table: PPO and four more.
LEARNERS = ("ppo", "recurrent_ppo", "sac", "tqc", "cmaes")
#: The scenario PPO trains on by default, and the suite every other learner trains on.
PPO_SCENARIO, SUITE_SCENARIO = "nonstationary", "suite"


def training_scenario(learner: str, scenario: str | None) -> str:
    """The scenario ``learner`` trains on: ``scenario``, or its default (PPO: ``nonstationary``;
    the others train the general tuner on the ``suite`` only).

    Raises
    ------
    ArgumentError
        An unknown learner, or another learner than PPO given a scenario other than the suite.
    """
    if learner not in LEARNERS:
        raise ArgumentError("learner", f"must be one of {', '.join(LEARNERS)}", learner)
    if learner == "ppo":
        return scenario or PPO_SCENARIO
    if scenario not in (None, SUITE_SCENARIO):
        raise ArgumentError(
            "scenario",
            f"must be {SUITE_SCENARIO} for learner {learner} (it trains the general tuner on "
            "the suite; other scenarios are for ppo)",
            scenario,
        )
    return SUITE_SCENARIO
