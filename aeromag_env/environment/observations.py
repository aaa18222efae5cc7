"""Every observation the tuning environment can give, one entry each: the registry.

An environment's observation is a tuple of names chosen from :data:`REGISTRY`
(:attr:`aeromag_env.environment.config.EnvConfig.observations`), in the order of its columns.
Each entry names the observation, says what it measures and in which unit, gives its bounds
(the compiled step clips to them) and what it needs of the configuration; the compiled step
writes it with one function of :mod:`aeromag_env.environment.observe`, found by the entry's
position in the registry (:func:`observation_id`). The observation space's size, names and
bounds come from here only.

Adding an observation is one entry here, one writer in :mod:`~aeromag_env.environment.observe`
and one test. This module is light (no numba, no simulator), so documentation and the ids can
read it.
"""

from __future__ import annotations

from dataclasses import dataclass

from aeromag_env.errors import ConfigError

#: Observations are log10 ratios clipped to ±OBS_LIMIT, unless an entry gives its own range.
OBS_LIMIT = 8.0


@dataclass(frozen=True, kw_only=True)
class Observation:
    """One registry entry.

    Attributes
    ----------
    name : the observation's name (a column of the observation vector)
    description : what it measures, one or two sentences
    unit : its unit (``decades`` for a log10 ratio)
    low, high : its bounds; the compiled step clips the value to them
    needs : what it needs of the action mapping: ``"permanent_action"`` (a separate action for
        the T_p block, :attr:`ActionSpec.permanent` not ``joint``) or nothing
    """

    name: str
    description: str
    unit: str
    low: float = -OBS_LIMIT
    high: float = OBS_LIMIT
    needs: tuple[str, ...] = ()


#: The registry, in the order the compiled step writes the observations it is given.
REGISTRY: tuple[Observation, ...] = (
    Observation(
        name="log_ror",
        description="log10 ROR: the windowed innovation trace over its predicted trace "
        "(eq. 22) over the statistics window; 0 before data",
        unit="decades",
    ),
    Observation(
        name="log_qoq",
        description="log10 QOQ: tr(K C_r Kᵀ) / tr Q (covariance matching); 0 before data",
        unit="decades",
    ),
    Observation(
        name="log_q_scale",
        description="log10 of the cumulative Q scale relative to Q(0) (with a separate T_p "
        "action: of the induced and eddy blocks)",
        unit="decades",
    ),
    Observation(
        name="log_r_scale",
        description="log10 of the cumulative R scale relative to R(0)",
        unit="decades",
    ),
    Observation(
        name="whiteness",
        description="lag-1 autocorrelation of the innovations over the statistics window",
        unit="1",
        low=-1.0,
        high=1.0,
    ),
    Observation(
        name="progress",
        description="progress through the flight (samples flown over its length)",
        unit="1",
        low=0.0,
        high=1.0,
    ),
    Observation(
        name="log_recent_ror",
        description="log10 ROR over the last recent_samples updates only: it reacts to an "
        "interference step within a decision window, the windowed ROR only slowly",
        unit="decades",
    ),
    Observation(
        name="log_qp_scale",
        description="log10 of the cumulative Q scale of the permanent-field block T_p",
        unit="decades",
        needs=("permanent_action",),
    ),
    Observation(
        name="log_innovation_power",
        description="log10 of the mean innovation power mean |r|² over the statistics window "
        "over tr R(0): the noise level, whatever R is",
        unit="decades",
    ),
    Observation(
        name="log_mean_innovation_power",
        description="log10 of the power of the mean innovation |mean r|² over the last "
        "recent_samples updates over tr R(0): noise averages out of it, a step does not",
        unit="decades",
    ),
    Observation(
        name="log_step_statistic",
        description="log10 of the two-window change statistic: the mean innovation of the "
        "last recent_samples updates against that of the rest of the statistics window, over "
        "the latter's innovation variance (about 0 without a change at any noise level)",
        unit="decades",
    ),
    Observation(
        name="log_turn_rate",
        description="log10 of the RMS of |Ṫ|/|T| over the last decision window: the "
        "aircraft's angular rate across the Earth field (the lower bound without a turn)",
        unit="log10 rad/s",
    ),
    Observation(
        name="log_innovation_bias",
        description="log10 of M |mean r|² / tr C over the statistics window: the mean "
        "innovation against zero over the innovations' covariance trace (about 0 for a "
        "consistent filter); a step the filter missed keeps it high",
        unit="decades",
    ),
)
#: Every name of the registry, in its order.
NAMES = tuple(entry.name for entry in REGISTRY)
_BY_NAME = {entry.name: entry for entry in REGISTRY}
#: The paper's two inputs (§3.4), the observation of the ``paper`` preset.
PAPER_OBSERVATIONS = ("log_ror", "log_qoq")


def entry(name: str) -> Observation:
    """The registry entry of ``name``; a one-line ConfigError naming the valid ones."""
    try:
        return _BY_NAME[name]
    except (KeyError, TypeError):
        raise ConfigError(
            f"unknown observation {name!r}; valid observations: {', '.join(NAMES)}"
        ) from None


def observation_id(name: str) -> int:
    """The position of ``name`` in the registry: the compiled step's id of the observation."""
    return NAMES.index(entry(name).name)


def check_observations(names: object, permanent_action: bool) -> None:
    """A one-line ConfigError unless ``names`` is a tuple of distinct registry names that starts
    with the paper's two (every policy reads them at columns 0 and 1) and whose needs are met
    (``permanent_action``: the action mapping has a T_p action)."""
    if not isinstance(names, tuple) or names[: len(PAPER_OBSERVATIONS)] != PAPER_OBSERVATIONS:
        raise ConfigError(
            f"observations must be a list of names starting with {', '.join(PAPER_OBSERVATIONS)}"
            f", got {names!r}"
        )
    for name in names:
        needs = entry(name).needs
        if "permanent_action" in needs and not permanent_action:
            raise ConfigError(
                f"observations: {name!r} needs a T_p action (action.permanent 'graded' or 'gate')"
            )
    repeated = sorted({n for n in names if names.count(n) > 1})
    if repeated:
        raise ConfigError(f"observations repeat {', '.join(repeated)}; give each once")
