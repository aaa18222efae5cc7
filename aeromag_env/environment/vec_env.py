"""Gymnasium vector environment of ``AeroMagCompensation-v0``: N flights, one compiled step."""

from __future__ import annotations

import copy
import functools
from dataclasses import replace
from typing import Any, NamedTuple

import numpy as np
from gymnasium.error import ResetNeeded
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from aeromag_env.compensation.arrays import packed
from aeromag_env.compensation.kalman import FilterState
from aeromag_env.compensation.kalman_batch import BatchFilterState
from aeromag_env.compensation.kernel_layout import INTS
from aeromag_env.compensation.model import FilterConfig
from aeromag_env.environment import kernels
from aeromag_env.environment.checks import RESET_OPTIONS, reset_options
from aeromag_env.environment.env import AeroMagCompensationEnv, EnvConfig, step_settings
from aeromag_env.environment.info import info, info_rows, put_infos
from aeromag_env.environment.layout import N_OUT, N_RUN, BatchArrays, EnvArrays
from aeromag_env.environment.prefetch import FlightKey, FlightPrefetcher, simulate
from aeromag_env.environment.spaces import (
    action_size,
    check_actions,
    non_finite_actions,
)
from aeromag_env.environment.step_arrays import StepArrays, step_arrays

#: The actions' types the compiled step takes as they are (others are converted first).
KERNEL_DTYPES = (np.dtype(np.float32), np.dtype(np.float64))

#: The keys ``reset(options=...)`` takes: the single environment's and ``reset_mask``.
VEC_RESET_OPTIONS = ("reset_mask", *RESET_OPTIONS, "filter_method")


class StepResults(NamedTuple):
    """The arrays a step leaves its results in (the same arrays for the environment's life:
    read them, copy what is kept, before the next step or reset)."""

    obs: np.ndarray  #: (N, dim) float32 observations
    reward: np.ndarray  #: (N,) float64 rewards
    terminated: np.ndarray  #: (N,) bool
    truncated: np.ndarray  #: (N,) bool
    ended: np.ndarray  #: (N,) bool: terminated or truncated


class AeroMagCompensationVecEnv(VectorEnv):
    """N independent ``AeroMagCompensation-v0`` environments advanced in one compiled call.

    ## Description

    Environment i is :class:`~aeromag_env.environment.env.AeroMagCompensationEnv` (same
    configuration, spaces, reward and episode end): given the same reset seed and the same actions
    it returns bitwise the same observations, rewards, terminations, truncations and infos as
    ``gym.make_vec(..., vectorization_mode="sync")`` over single environments (tested). The step
    of all N environments — action check, action mapping, filter over K samples, reward,
    observation, step count, end flags — is one compiled call
    (:func:`aeromag_env.environment.kernels.env_step_batch`), spread over the cores for many
    environments; only resets (simulating a new flight) run in Python, one environment at a time
    (or ahead, in a worker process: Prefetching below).

    ## Spaces

    ``single_action_space`` and ``single_observation_space`` are the single environment's;
    ``action_space`` and ``observation_space`` batch them: actions (N, 2), or (N, 3) with a T_p
    action; observations (N, len(config.observations)) float32. Actions are clipped to
    [-1, 1]; a wrong shape, values that are not real numbers
    (complex, bool, text, objects) or a non-finite value (naming its environment) raise
    ``ValueError``.

    ## Autoreset

    ``autoreset_mode`` (``metadata["autoreset_mode"]``) as in Gymnasium 1.x:

    * ``NEXT_STEP`` (default): the step after environment i ended resets it (a new flight from
      its generator) and ignores its action; that step returns the first observation of the
      new flight, reward 0, not terminated nor truncated, and the reset's info.
    * ``SAME_STEP``: the ending step resets at once; ``info["final_obs"]`` and
      ``info["final_info"]`` hold the last observation and info of the ended episode.
    * ``DISABLED``: the caller resets ended environments with
      ``reset(options={"reset_mask": mask})``; stepping an ended environment is an error.

    Flights of different scenarios have different lengths (``episode_lengths``); each
    environment ends its own episode.

    ## Prefetching

    With ``prefetch=True`` a worker process simulates each environment's next flight while the
    current one runs (:mod:`aeromag_env.environment.prefetch`), so resets mostly cost no simulation
    time. With autoreset the next flight is known (the environment's generator); with ``DISABLED``
    the caller names it with :meth:`prefetch_next`. The flights are the same either way.

    ## Seeding

    ``reset(seed=s)`` seeds environment i with ``s + i`` (a list gives one seed per
    environment), like Gymnasium's vectorizers; each environment then draws its flights from its
    own generator, as the single environment does. ``options={"scenario": name}`` switches the
    scenario of the environments being reset; ``options={"filter_method": m}`` runs their
    filters with the built-in adaptation of method ``m`` (as the single environment's option),
    for their following episodes too, autoresets included, until another ``filter_method``;
    ``scenario``, ``filter_method`` and ``reset_mask`` are the only option keys (others, or
    options that are not a dict, are refused).

    ## Arguments

    ``gym.make_vec("AeroMagCompensation-v0", num_envs=N,
    vectorization_mode="vector_entry_point", config=..., autoreset_mode=..., **overrides)``
    with the single environment's ``config`` and keyword shortcuts, ``prefetch`` and
    ``max_episode_steps`` (each environment truncated after that many steps of its episode, as
    ``gym.make(..., max_episode_steps=N)`` truncates the single one), and ``flight_cache``
    (keep the last N simulated flights: environments reset to the same flight simulate it
    once). The per-scenario ids (``AeroMag/Nonstationary-v0``…,
    :mod:`aeromag_env.environment.ids`) make it too. No
    ``render_mode`` None or ``"rgb_array"`` (:meth:`render`: a frame per environment, as the
    single env draws it but against samples). :meth:`close` stops the prefetching worker.
    """

    def __init__(
        self,
        num_envs: int = 1,
        config: EnvConfig | dict | None = None,
        render_mode: str | None = None,
        autoreset_mode: str | AutoresetMode = AutoresetMode.NEXT_STEP,
        prefetch: bool = False,
        max_episode_steps: int | None = None,
        flight_cache: int = 0,
        **overrides: Any,
    ) -> None:
        if not (isinstance(num_envs, int | np.integer) and num_envs >= 1):
            raise ValueError(f"num_envs must be an integer ≥ 1, got {num_envs!r}")
        if max_episode_steps is not None and not (
            isinstance(max_episode_steps, int | np.integer)
            and not isinstance(max_episode_steps, bool)
            and max_episode_steps >= 1
        ):
            raise ValueError(
                f"max_episode_steps must be an integer ≥ 1 or None, got {max_episode_steps!r}"
            )
        if render_mode not in (None, "rgb_array"):
            raise ValueError(f"render_mode must be None or 'rgb_array', got {render_mode!r}")
        template = AeroMagCompensationEnv(config, **overrides)
        self.config = template.config
        self.num_envs = int(num_envs)
        self.autoreset_mode = AutoresetMode(autoreset_mode)
        self.render_mode = render_mode
        self.metadata = {"render_modes": ["rgb_array"], "autoreset_mode": self.autoreset_mode}
        self.single_action_space = template.action_space
        self.single_observation_space = template.observation_space
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self._settings = step_settings(self.config)
        n = self.num_envs
        self._rngs: list[np.random.Generator | None] = [None] * n
        self.scenarios = [self.config.scenario] * n
        #: Each environment's filter method (None: its scenario's own).
        self.filter_methods: list[str | None] = [None] * n
        self.flight_seeds = np.zeros(n, np.int64)
        self._filters: BatchFilterState | None = None
        self._truth = np.zeros((n, 0, 3))
        self._run = np.zeros((n, N_RUN))
        self._score_start = np.zeros(n, np.int64)
        self._obs = np.zeros((n, self._settings.low.size), np.float32)
        self._out = np.zeros((n, N_OUT))
        self._active = np.ones(n, bool)  # the environments a step moves (the others restart)
        self._steps = np.zeros(n, np.int64)  # steps of each environment's current episode
        self._everyone = np.ones(n, bool)  # the mask of a step without restarts (never written)
        self._actions = np.zeros((n, action_size(self.config)))  # the step's checked actions
        self.results = StepResults(
            self._obs, np.zeros(n), np.zeros(n, bool), np.zeros(n, bool), np.zeros(n, bool)
        )
        self._ended = self.results.ended
        # the compiled step's arrays in one object (rebuilt after a reset, which may reallocate
        # them)
        self._step_arrays: StepArrays | None = None
        self.max_episode_steps = None if max_episode_steps is None else int(max_episode_steps)
        self._prefetcher = FlightPrefetcher() if prefetch else None
        if not (isinstance(flight_cache, int | np.integer) and flight_cache >= 0):
            raise ValueError(f"flight_cache must be an integer ≥ 0, got {flight_cache!r}")
        # environments that fly the same flight (a search scoring candidates on common flights)
        # simulate it once; the arrays are only read (copied into the stacked filters)
        self._simulate = (
            functools.lru_cache(int(flight_cache))(simulate) if flight_cache else simulate
        )

    @property
    def episode_lengths(self) -> np.ndarray:
        """(N,) samples of each environment's current flight."""
        return self._need_filters().n.copy()

    @property
    def filters(self) -> BatchFilterState:
        """The stacked filter states (read them; stepping goes through :meth:`step`)."""
        return self._need_filters()

    def render(self) -> tuple[np.ndarray, ...] | None:
        """Each environment's episode so far as an RGB array; None without ``rgb_array``."""
        if self.render_mode != "rgb_array":
            return None
        from aeromag_env.environment.render import render_vector

        f = self._need_filters()
        return render_vector(self.scenarios, f.ints[:, INTS.k], self._truth, f)

    def reset(
        self, *, seed: int | list[int | None] | None = None, options: dict | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        options = reset_options(options, VEC_RESET_OPTIONS)
        super().reset(seed=int(seed) if isinstance(seed, int | np.integer) else None)
        seeds = _per_env_seeds(seed, self.num_envs)
        mask = options.pop("reset_mask", None)
        if "filter_method" in options:  # refused in one line before any environment takes it
            FilterConfig(method=options["filter_method"])
        if mask is None:
            mask = np.ones(self.num_envs, bool)
        elif self._filters is None:
            raise ResetNeeded("reset all environments (no reset_mask) before a partial reset")
        else:
            mask = _checked_mask(mask, self.num_envs)
        indices = np.flatnonzero(mask)
        flights = [self._new_flight(int(i), seeds[i], options) for i in indices]
        if self._filters is None:
            self._filters = BatchFilterState([state for state, _ in flights])
        for i, (state, truth) in zip(indices, flights, strict=True):
            self._load(int(i), state, truth)
        infos: dict[str, Any] = {}
        _put(infos, "flight_seed", self.flight_seeds, mask)
        return self._obs.copy(), infos

    def step(
        self, actions: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        infos: dict[str, Any] = {}
        stepped = self._restart_ended(infos)
        self._advance(actions, stepped)
        stepped = self._everyone if stepped is None else stepped
        r = self.results
        rewards, terminated, truncated = r.reward.copy(), r.terminated.copy(), r.truncated.copy()
        if self.autoreset_mode == AutoresetMode.SAME_STEP and self._any_ended():
            obs = self._same_step_reset(infos, stepped)
        else:
            obs = self._obs.copy()
            self._step_infos(infos, stepped)
        return obs, rewards, terminated, truncated, infos

    def step_in_place(self, actions: np.ndarray) -> int:
        """:meth:`step` of every environment for an adapter that wants no more (stable-baselines3:
        :class:`~aeromag_env.environment.sb3.AeroMagSB3VecEnv`): one compiled call, the results
        left in :attr:`results`, no infos built (:meth:`info_rows` builds them), no reset. Returns
        the number of environments whose episode ended. Autoreset must be disabled; stepping an
        environment that ended and was not reset is refused (``ResetNeeded``)."""
        if self.autoreset_mode != AutoresetMode.DISABLED:
            raise ValueError("step_in_place needs autoreset_mode=AutoresetMode.DISABLED")
        return self._advance(actions, None)

    def info_rows(self, indices: np.ndarray | None = None) -> list[dict[str, Any]]:
        """The single env's info of each environment after the last step (of ``indices`` only,
        if given), one dict each: built straight from the outcome rows."""
        ints = self._need_filters().ints
        if indices is None:
            return info_rows(self._out, ints, self.flight_seeds)
        return info_rows(self._out[indices], ints[indices], self.flight_seeds[indices])

    def _real_actions(self, actions: object) -> np.ndarray:
        """``actions`` as a float array for the compiled step, which copies them into the step's
        own, checking their shape and that they are finite: a two-dimensional array of native
        float32 or float64 (every step of a trainer) as it is, anything else through
        :func:`check_actions` (which converts it, or raises what it refuses; the compiled step
        is compiled for those types only)."""
        if type(actions) is np.ndarray and actions.ndim == 2 and actions.dtype in KERNEL_DTYPES:
            return actions
        if self.autoreset_mode == AutoresetMode.DISABLED and self._any_ended():
            self._refuse(-1 - kernels.NOT_RESET * self.num_envs)  # refused first, as ever
        return check_actions(actions, *self._actions.shape, out=self._actions, finite=False)

    def _pack(self) -> StepArrays:
        """The compiled step's arrays in one object, built once per allocation (a reset may
        reallocate the filters' and the truth's arrays)."""
        filters, r = self._need_filters(), self.results
        batch = BatchArrays(
            *(self._active, filters.mode, filters.n, self._score_start, self._steps),
            *(r.reward, r.terminated, r.truncated, r.ended),
        )
        envs = EnvArrays(self._actions, self._run, self._truth, self._obs, self._out)
        self._step_arrays = step_arrays(
            packed(batch), packed(envs), packed(self._settings), packed(filters.arrays())
        )
        return self._step_arrays

    def _advance(self, actions: np.ndarray, stepped: np.ndarray | None) -> int:
        """Step the environments of ``stepped`` (None: all; the others' outcome rows zeroed) in
        one compiled call, the results in :attr:`results`; the number whose episode ended."""
        actions = self._real_actions(actions)
        arrays = self._step_arrays or self._pack()
        if stepped is not None:
            np.copyto(self._active, stepped)
        try:
            limit = self.max_episode_steps or 0
            ended = kernels.env_step_batch(arrays, actions, self.num_envs, limit)
        finally:
            if stepped is not None:
                self._active.fill(True)
        if ended < 0:
            self._refuse(ended, actions)
        return ended

    def _refuse(self, code: int, actions: np.ndarray | None = None) -> None:
        """The error of :func:`~aeromag_env.environment.kernels.env_step_batch`'s refusal
        ``code`` (nothing moved) for ``actions``."""
        kind, i = kernels.refusal(code, self.num_envs)
        if kind == kernels.NOT_SHAPED:
            check_actions(actions, *self._actions.shape, finite=False)  # says what is wrong
            raise ValueError(f"actions must have shape {self._actions.shape}")
        if kind != kernels.NOT_RESET:
            raise non_finite_actions(i, self._actions)
        raise ResetNeeded(
            f"environments {np.flatnonzero(self._ended).tolist()} ended; reset them with "
            "reset(options={'reset_mask': mask})"
        )

    def _restart_ended(self, infos: dict[str, Any]) -> np.ndarray | None:
        """With ``NEXT_STEP``, environments that ended on the previous step restart now, which
        is their whole step: returns the environments to step (None: all). (``DISABLED``: the
        compiled step refuses an ended environment.)"""
        if self.autoreset_mode != AutoresetMode.NEXT_STEP or not self._any_ended():
            return None
        restart = self._ended.copy()
        for i in np.flatnonzero(restart):
            self._load(int(i), *self._new_flight(int(i), None, {}))
        _put(infos, "flight_seed", self.flight_seeds, restart)
        return ~restart

    def _any_ended(self) -> bool:
        """Whether an environment's episode ended on the last step (``count_nonzero``: a
        fraction of ``ndarray.any``'s cost, asked twice a step)."""
        return bool(np.count_nonzero(self._ended))

    def _need_filters(self) -> BatchFilterState:
        if self._filters is None:
            raise ResetNeeded("call reset() before step()")
        return self._filters

    def prefetch_next(self, i: int, seed: int | None = None) -> None:
        """Environment i's next reset will be seeded with ``seed`` (None: it draws from its own
        generator): have that flight simulated now (no-op without ``prefetch``)."""
        if self._prefetcher is None:
            return
        rng = seeding.np_random(seed)[0] if seed is not None else copy.deepcopy(self._rngs[i])
        if rng is None:  # never reset: its first flight is not known yet
            return
        key = FlightKey(self.scenarios[i], int(rng.integers(2**31)), self.config.duration_s)
        self._prefetcher.expect(i, key)

    def close_extras(self, **kwargs: Any) -> None:
        if self._prefetcher is not None:
            self._prefetcher.close()

    def _new_flight(
        self, i: int, seed: int | None, options: dict
    ) -> tuple[FilterState, np.ndarray]:
        """Environment i's next flight, drawn as the single env's reset draws it: its fresh
        filter and true interference (n, 3) [nT]."""
        if seed is not None or self._rngs[i] is None:
            self._rngs[i] = seeding.np_random(seed)[0]
        if "scenario" in options:
            self.scenarios[i] = options["scenario"]
        if "filter_method" in options:
            self.filter_methods[i] = options["filter_method"]
        rng = self._rngs[i]
        assert rng is not None
        self.flight_seeds[i] = int(rng.integers(2**31))
        key = FlightKey(self.scenarios[i], int(self.flight_seeds[i]), self.config.duration_s)
        flight = self._simulate(key) if self._prefetcher is None else self._prefetcher.take(i, key)
        if self.autoreset_mode != AutoresetMode.DISABLED:
            self.prefetch_next(i)  # the autoreset after this flight draws from the generator
        cfg, method = flight.filter_cfg, self.filter_methods[i]
        if method is not None:
            cfg = replace(cfg, method=method)
        state = FilterState(cfg, flight.y, flight.t_b, flight.tdot_b, store_states=False)
        return state, flight.truth_interf

    def _load(self, i: int, state: FilterState, truth: np.ndarray) -> None:
        filters = self._need_filters()
        filters.load(i, state)
        capacity = filters.y.shape[1]
        if self._truth.shape[1] < capacity:  # a longer flight than any so far
            grown = np.full((self.num_envs, capacity, 3), np.nan)
            grown[:, : self._truth.shape[1]] = self._truth
            self._truth = grown
        self._truth[i, : state.n] = truth
        self._truth[i, state.n :] = np.nan
        self._run[i] = 0.0
        self._score_start[i] = int(self.config.score_from * state.n)
        self._obs[i] = 0.0
        self._ended[i] = False
        self._steps[i] = 0
        self._step_arrays = None  # the filters' or the truth's arrays may have grown

    def _step_infos(self, infos: dict[str, Any], stepped: np.ndarray) -> None:
        """The single env's step infos of the ``stepped`` environments, batched."""
        filters = self._need_filters()
        put_infos(infos, self._out, filters.ints, self.flight_seeds, stepped, _put)

    def _info(self, i: int) -> dict[str, Any]:
        """The single env's info of environment i at the end of its episode."""
        return info(self._out[i], self._need_filters().ints[i], int(self.flight_seeds[i]))

    def _same_step_reset(self, infos: dict[str, Any], stepped: np.ndarray) -> np.ndarray:
        """Reset the ended environments at once; their last observation and info go to
        ``final_obs`` and ``final_info`` (Gymnasium's ``SAME_STEP`` layout)."""
        ended = self._ended.copy()
        self._step_infos(infos, stepped & ~ended)
        for i in np.flatnonzero(ended):
            final = {"final_obs": self._obs[i].copy(), "final_info": self._info(int(i))}
            infos.update(self._add_info(infos, final, int(i)))
            self._load(int(i), *self._new_flight(int(i), None, {}))
        _put(infos, "flight_seed", self.flight_seeds, ended)
        return self._obs.copy()


def _put(infos: dict[str, Any], key: str, values: np.ndarray, mask: np.ndarray) -> None:
    """Set ``infos[key][mask]`` and its mask ``infos["_" + key]`` (Gymnasium's vector info
    layout: zeros where an environment has no entry)."""
    count = np.count_nonzero(mask)
    if count == 0:
        return
    if key not in infos:
        if count == mask.size:  # the usual case: every environment has the entry
            infos[key], infos[f"_{key}"] = values.copy(), mask.copy()
            return
        infos[key] = np.zeros(mask.size, values.dtype)
        infos[f"_{key}"] = np.zeros(mask.size, bool)
    infos[key][mask] = values[mask]
    infos[f"_{key}"] |= mask


def _per_env_seeds(seed: int | list[int | None] | None, n: int) -> list[int | None]:
    if seed is None:
        return [None] * n
    if isinstance(seed, int | np.integer):
        return [int(seed) + i for i in range(n)]
    seeds = list(seed)
    if len(seeds) != n:
        raise ValueError(f"reset needs one seed per environment ({n}), got {len(seeds)}")
    return seeds


def _checked_mask(mask: object, n: int) -> np.ndarray:
    if not (isinstance(mask, np.ndarray) and mask.dtype == np.bool_ and mask.shape == (n,)):
        raise ValueError(f"options['reset_mask'] must be a bool numpy array of shape ({n},)")
    if not mask.any():
        raise ValueError("options['reset_mask'] must select at least one environment")
    return mask
