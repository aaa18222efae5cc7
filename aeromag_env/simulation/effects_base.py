"""The effect protocol of the effects library (:mod:`aeromag_env.simulation.effects`): what an
effect sees of a flight, its candidate regressor groups, the base class with parameter
validation, and the column builders and constants the effects share."""

from __future__ import annotations

import datetime as _dt
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

import numpy as np

from aeromag_env.errors import ConfigError

#: Scale of the quadratic terms of ``induced_second_order`` [nT].
FIELD_SCALE_NT = 50_000.0
#: Legendre degrees of the slow body-frame drift.
DRIFT_DEGREES = (1, 2)
#: Knot spacing of the cubic B-splines of ``external_field_variation`` [s].
EXTERNAL_KNOT_SPACING_S = 120.0
#: Grids of the profiled time constants [s].
EDDY_TAU_GRID_S = tuple(float(v) for v in np.geomspace(0.02, 2.0, 9))
LAG_GRID_S = tuple(float(v) for v in np.geomspace(0.005, 0.5, 21))
#: Axis names of the body and navigation (NED) frames, as used in column labels.
AXES = ("x", "y", "z")
NED = ("n", "e", "d")


@dataclass
class EffectContext:
    """What an effect may see of a flight, in package units.

    ``signal`` is the fluxgate signal before the effect (simulation only: ``sensor_lag`` shifts
    it in time and the absorbed sensor errors act on it); ``rng`` draws random parts (simulation
    only); ``start`` is the UTC time of ``tt = 0``.
    """

    tt: np.ndarray
    c_nb: np.ndarray
    t_b: np.ndarray
    tdot_b: np.ndarray
    t2dot_b: np.ndarray
    alt: np.ndarray
    aux: dict[str, np.ndarray] = field(default_factory=dict)
    signal: np.ndarray | None = None
    rng: np.random.Generator | None = None
    start: _dt.datetime | None = None

    @property
    def n(self) -> int:
        return int(self.tt.size)

    def span(self) -> tuple[float, float]:
        return float(self.tt[0]), float(self.tt[-1])


@dataclass
class Group:
    """Candidate regressors of one effect: ``columns`` (n, 3, p) [nT per unit coefficient]."""

    effect: str
    channel: str | None
    columns: np.ndarray
    labels: list[str]
    #: Coefficients → EffectConfig parameters that re-simulate ``columns @ beta`` exactly.
    to_parameters: Callable[[np.ndarray], dict[str, Any]]
    #: Value of a non-linear parameter this group was built for (a time constant or lag [s]);
    #: groups of one effect and channel that differ only in it are profiled: the best enters.
    profile: float | None = None
    #: Builds the group for another value of ``profile`` (to refine it between grid points).
    rebuild: Callable[[float], Group] | None = None

    @property
    def family(self) -> str:
        return self.effect if self.channel is None else f"{self.effect}[{self.channel}]"


def legendre(tt: np.ndarray, span: tuple[float, float], degrees: tuple[int, ...]) -> np.ndarray:
    """Legendre polynomials of ``tt`` mapped from ``span`` to [-1, 1].

    Parameters
    ----------
    tt : numpy.ndarray
        Times (n,) [s].
    span : tuple of float
        Times mapped to -1 and +1 [s].
    degrees : tuple of int
        Polynomial degrees, one column each.

    Returns
    -------
    numpy.ndarray
        (n, len(degrees)).
    """
    t0, t1 = span
    x = (2.0 * (tt - t0) / max(t1 - t0, 1e-9)) - 1.0
    return np.column_stack([np.polynomial.legendre.Legendre.basis(d)(x) for d in degrees])


def spline_knots(
    span: tuple[float, float], spacing_s: float = EXTERNAL_KNOT_SPACING_S
) -> np.ndarray:
    """Knot vector of clamped cubic B-splines on ``span`` with about ``spacing_s`` between knots.

    Parameters
    ----------
    span : tuple of float
        First and last time [s].
    spacing_s : float, optional
        Wanted spacing of the inner knots [s].

    Returns
    -------
    numpy.ndarray
        The knots, the end knots repeated (clamped).
    """
    t0, t1 = span
    inner = np.linspace(t0, t1, max(2, round((t1 - t0) / spacing_s) + 1))
    return np.r_[[t0] * 3, inner, [t1] * 3]


def spline_basis(tt: np.ndarray, knots: np.ndarray) -> np.ndarray:
    """Cubic B-spline basis on ``knots`` (clamped); times outside are clipped to the knots.

    Parameters
    ----------
    tt : numpy.ndarray
        Times (n,) [s].
    knots : numpy.ndarray
        Knot vector, e.g. from :func:`spline_knots`.

    Returns
    -------
    numpy.ndarray
        (n, len(knots) − 4).
    """
    from scipy.interpolate import BSpline

    x = np.clip(tt, knots[0], knots[-1])
    return np.asarray(BSpline.design_matrix(x, knots, 3).toarray())


def nav_columns(ctx: EffectContext, weights: np.ndarray) -> np.ndarray:
    """Columns ``w_m(t) C_nbᵀ e_j`` for each weight m and NED axis j.

    Parameters
    ----------
    ctx : EffectContext
        Supplies the attitude ``c_nb`` (n, 3, 3).
    weights : numpy.ndarray
        (n, m).

    Returns
    -------
    numpy.ndarray
        (n, 3, 3·m), NED axis fastest.
    """
    c_bn_cols = np.transpose(ctx.c_nb, (0, 2, 1))  # (n, 3 body, 3 nav): column j = C_bnᵀ e_j
    cols = weights[:, None, :, None] * c_bn_cols[:, :, None, :]  # (n, 3, m, 3)
    return cols.reshape(ctx.n, 3, -1)


def body_columns(weights: np.ndarray) -> np.ndarray:
    """Columns ``w_m(t) e_i`` for each weight m and body axis i.

    Parameters
    ----------
    weights : numpy.ndarray
        (n, m).

    Returns
    -------
    numpy.ndarray
        (n, 3, 3·m), body axis fastest.
    """
    n, m = weights.shape
    cols = np.zeros((n, 3, m, 3))
    for i in range(3):
        cols[:, i, :, i] = weights
    return cols.reshape(n, 3, -1)


def vector_parameter(params: dict[str, Any], key: str, size: int) -> np.ndarray | None:
    """Parameter ``key`` of an effect as a float vector.

    Parameters
    ----------
    params : dict
        The effect's parameters.
    key : str
        Parameter name.
    size : int
        Number of values.

    Returns
    -------
    numpy.ndarray or None
        (size,), or None if ``params`` does not have ``key``.
    """
    v = params.get(key)
    return None if v is None else np.asarray(v, float).reshape(size)


def _nonzero(value: Any) -> bool:
    """Whether a checked parameter value (a number or numbers; None: not given) has a non-zero."""
    return value is not None and bool(np.any(np.asarray(value, float) != 0))


class Effect:
    """Base class: name, parameters by name and size, and the channels it needs."""

    name = ""
    description = ""
    #: Base-model term that absorbs this effect entirely, or None if it can be identified.
    absorbed_by: str | None = None
    #: Parameter name → number of values (0: a scalar).
    parameter_sizes: Mapping[str, int] = MappingProxyType({})
    #: Prefixes of auxiliary channels the effect follows; () if it needs none.
    channel_prefixes: tuple[str, ...] = ()
    #: A channel is optional (the effect also has a channel-less form).
    channel_optional = False
    #: The parameters that set the size of the field: without one of them non-zero the effect
    #: adds nothing, and an entry is refused.
    strength: tuple[str, ...] = ()

    def check(self, channel: str | None, params: dict[str, Any]) -> None:
        unknown = sorted(set(params) - set(self.parameter_sizes))
        if unknown:
            raise ConfigError(
                f"effect {self.name}: unknown parameter(s) {', '.join(unknown)}; "
                f"valid: {', '.join(self.parameter_sizes)}"
            )
        for key, value in params.items():
            size = self.parameter_sizes[key]
            try:
                arr = np.asarray(value, float)
            except (TypeError, ValueError):
                raise ConfigError(f"effect {self.name}: {key} must be numbers") from None
            if size < 0:
                if arr.ndim != 1 or arr.size % -size:
                    raise ConfigError(
                        f"effect {self.name}: {key} needs a list of a multiple of {-size} numbers"
                    )
            elif (size == 0 and arr.ndim != 0) or (size and arr.size != size):
                want = "one number" if size == 0 else f"{size} numbers"
                raise ConfigError(f"effect {self.name}: {key} needs {want}, got {value!r}")
            if not np.all(np.isfinite(arr)):
                raise ConfigError(f"effect {self.name}: {key} must be finite")
        if self.channel_prefixes and channel is None and not self.channel_optional:
            raise ConfigError(
                f"effect {self.name} needs a channel ({'/'.join(self.channel_prefixes)}*)"
            )
        if channel is not None and not channel.startswith(self.channel_prefixes or ("\0",)):
            raise ConfigError(
                f"effect {self.name} cannot follow channel {channel!r}"
                + (f" (needs {'/'.join(self.channel_prefixes)}*)" if self.channel_prefixes else "")
            )
        if self.strength and not any(_nonzero(params.get(key)) for key in self.strength):
            raise ConfigError(
                f"effect {self.name} adds nothing: give {' or '.join(self.strength)} "
                f"(non-zero) among its parameters ({', '.join(self.parameter_sizes)})"
            )

    def simulate(
        self, ctx: EffectContext, channel: str | None, params: dict[str, Any]
    ) -> np.ndarray:
        raise NotImplementedError

    def groups(self, ctx: EffectContext) -> tuple[list[Group], str | None]:
        """Candidate groups from the channels present, and why none could be built (or None)."""
        raise NotImplementedError

    def _channel(self, ctx: EffectContext, channel: str | None) -> np.ndarray:
        if channel not in ctx.aux:
            raise ConfigError(
                f"effect {self.name} follows channel {channel!r}, which the flight does not have"
            )
        return ctx.aux[channel]
