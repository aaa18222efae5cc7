"""Effects library: extra physics beyond paper eq. 5, shared by the simulator and discovery.

Each effect has a canonical name (used verbatim in reports), a ``simulate`` that returns the
field it adds to the fluxgate signal (body axes, nT), and a ``groups`` that builds its candidate
regressor columns from the channels a flight has. The simulator injects what the discovery
workflow (:mod:`aeromag_env.discovery.workflow`) can name, and the workflow writes what it found
back as an
:class:`~aeromag_env.simulation.config.EffectConfig` whose ``simulate`` reproduces the fitted
columns, so a discovered model re-simulates exactly.

Effects the 21-state base model absorbs (a constant fluxgate offset into ``T_p``; scale,
non-orthogonality and misalignment into ``A``) are in the library too, marked ``absorbed_by``:
the simulator can inject them, and discovery shows they leave nothing to find.

Conventions: ``T`` body-frame Earth field, ``Ṫ``/``T̈`` its first/second time derivatives (central
differences, as the simulator's eddy field), ``C_nb`` body → NED; ``P_k`` Legendre polynomials
on the flight's time span mapped to [-1, 1] (parameter ``time_span_s``).
"""

from __future__ import annotations

import dataclasses
import datetime as _dt
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

import numpy as np

from aeromag_env.errors import ConfigError
from aeromag_env.geo.earth import external_variation_ned, first_order_lag

#: Scale of the quadratic terms of ``induced_second_order`` [nT].
FIELD_SCALE_NT = 50_000.0
#: Legendre degrees of the slow body-frame drift.
DRIFT_DEGREES = (1, 2)
#: Knot spacing of the cubic B-splines of ``external_field_variation`` [s].
EXTERNAL_KNOT_SPACING_S = 120.0
#: Grids of the profiled time constants [s].
EDDY_TAU_GRID_S = tuple(float(v) for v in np.geomspace(0.02, 2.0, 9))
LAG_GRID_S = tuple(float(v) for v in np.geomspace(0.005, 0.5, 21))
_AXES = ("x", "y", "z")
_NED = ("n", "e", "d")
_PAIRS = ((0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2))


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
    """Legendre polynomials of ``tt`` mapped from ``span`` to [-1, 1]; shape (n, len(degrees))."""
    t0, t1 = span
    x = (2.0 * (tt - t0) / max(t1 - t0, 1e-9)) - 1.0
    return np.column_stack([np.polynomial.legendre.Legendre.basis(d)(x) for d in degrees])


def spline_knots(
    span: tuple[float, float], spacing_s: float = EXTERNAL_KNOT_SPACING_S
) -> np.ndarray:
    """Knot vector of clamped cubic B-splines on ``span`` with about ``spacing_s`` between knots."""
    t0, t1 = span
    inner = np.linspace(t0, t1, max(2, round((t1 - t0) / spacing_s) + 1))
    return np.r_[[t0] * 3, inner, [t1] * 3]


def spline_basis(tt: np.ndarray, knots: np.ndarray) -> np.ndarray:
    """Cubic B-spline basis (n, len(knots) − 4) on ``knots`` (clamped)."""
    from scipy.interpolate import BSpline

    x = np.clip(tt, knots[0], knots[-1])
    return np.asarray(BSpline.design_matrix(x, knots, 3).toarray())


def _nav_columns(ctx: EffectContext, weights: np.ndarray) -> np.ndarray:
    """Columns ``w_m(t) C_nbᵀ e_j`` for each weight m and NED axis j: (n, 3, 3·m)."""
    c_bn_cols = np.transpose(ctx.c_nb, (0, 2, 1))  # (n, 3 body, 3 nav): column j = C_bnᵀ e_j
    cols = weights[:, None, :, None] * c_bn_cols[:, :, None, :]  # (n, 3, m, 3)
    return cols.reshape(ctx.n, 3, -1)


def _body_columns(weights: np.ndarray) -> np.ndarray:
    """Columns ``w_m(t) e_i`` for each weight m and body axis i: (n, 3, 3·m)."""
    n, m = weights.shape
    cols = np.zeros((n, 3, m, 3))
    for i in range(3):
        cols[:, i, :, i] = weights
    return cols.reshape(n, 3, -1)


def _vec(params: dict[str, Any], key: str, size: int) -> np.ndarray | None:
    v = params.get(key)
    return None if v is None else np.asarray(v, float).reshape(size)


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


class OnboardCurrent(Effect):
    name = "onboard_current"
    description = "field proportional to an auxiliary current/voltage channel: k · I(t)"
    parameter_sizes = MappingProxyType({"k_nt_per_unit": 3})
    channel_prefixes = ("cur_", "vol_")

    def simulate(
        self, ctx: EffectContext, channel: str | None, params: dict[str, Any]
    ) -> np.ndarray:
        k = _vec(params, "k_nt_per_unit", 3)
        return np.zeros((ctx.n, 3)) if k is None else self._channel(ctx, channel)[:, None] * k

    def groups(self, ctx: EffectContext) -> tuple[list[Group], str | None]:
        chans = [c for c in ctx.aux if c.startswith(self.channel_prefixes)]
        out = [
            Group(self.name, c, _body_columns(ctx.aux[c][:, None]),
                  [f"{c}·e_{a}" for a in _AXES], lambda b: {"k_nt_per_unit": b.tolist()})
            for c in chans
        ]  # fmt: skip
        return out, None if chans else "no cur_* or vol_* channel in the file"


class ExternalFieldVariation(Effect):
    name = "external_field_variation"
    description = (
        "slowly varying field fixed in the navigation frame (diurnal, Earth-model error), "
        "rotated into the body frame by the attitude"
    )
    parameter_sizes = MappingProxyType(
        {
            "offset_ned_nt": 3,
            "daily_amplitude_nt": 0,
            "fogm_std_nt": 0,
            "fogm_tau_s": 0,
            "smoothing_s": 0,
            "spline_ned_nt": -3,
            "spline_knots_s": -1,
        }
    )

    def simulate(
        self, ctx: EffectContext, channel: str | None, params: dict[str, Any]
    ) -> np.ndarray:
        from aeromag_env.geo.frames import nav_to_body

        d_n = np.zeros((ctx.n, 3))
        offset = _vec(params, "offset_ned_nt", 3)
        if offset is not None:
            d_n += offset
        daily, fogm_std = params.get("daily_amplitude_nt", 0.0), params.get("fogm_std_nt", 0.0)
        if daily or fogm_std:
            if ctx.rng is None or ctx.start is None:
                raise ConfigError("external_field_variation: a random variation needs a simulation")
            d_n += external_variation_ned(
                ctx.tt, ctx.start, float(daily), float(fogm_std),
                float(params.get("fogm_tau_s", 600.0)), ctx.rng,
                float(params.get("smoothing_s", 60.0)),
            )  # fmt: skip
        if "spline_ned_nt" in params:
            knots = np.asarray(params["spline_knots_s"], float)
            coef = np.asarray(params["spline_ned_nt"], float).reshape(-1, 3)
            if coef.shape[0] != knots.size - 4:
                raise ConfigError(
                    "external_field_variation: spline_ned_nt needs 3 values per "
                    "B-spline (len(spline_knots_s) − 4)"
                )
            d_n += spline_basis(ctx.tt, knots) @ coef
        return nav_to_body(ctx.c_nb, d_n)

    def groups(self, ctx: EffectContext) -> tuple[list[Group], str | None]:
        knots = spline_knots(ctx.span())
        basis = spline_basis(ctx.tt, knots)
        cols = _nav_columns(ctx, basis)
        labels = [f"N{m}(t)·C_bn e_{a}" for m in range(basis.shape[1]) for a in _NED]
        to_params = lambda b: {"spline_ned_nt": b.tolist(), "spline_knots_s": knots.tolist()}  # noqa: E731
        return [Group(self.name, None, cols, labels, to_params)], None


class PermanentFieldDrift(Effect):
    name = "permanent_field_drift"
    description = (
        "slowly drifting field fixed in the body frame (temperature): k · (θ(t) − θ(t0)) with a "
        "temp_* channel, else a slow polynomial in time"
    )
    parameter_sizes = MappingProxyType(
        {
            "k_nt_per_unit": 3,
            "legendre_body_nt": 3 * len(DRIFT_DEGREES),
            "time_span_s": 2,
        }
    )
    channel_prefixes = ("temp_",)
    channel_optional = True

    def simulate(
        self, ctx: EffectContext, channel: str | None, params: dict[str, Any]
    ) -> np.ndarray:
        out = np.zeros((ctx.n, 3))
        k = _vec(params, "k_nt_per_unit", 3)
        if k is not None:
            if channel is None:
                raise ConfigError("permanent_field_drift: k_nt_per_unit needs a temp_* channel")
            theta = self._channel(ctx, channel)
            out += (theta - theta[0])[:, None] * k
        coef = _vec(params, "legendre_body_nt", 3 * len(DRIFT_DEGREES))
        if coef is not None:
            t0, t1 = params.get("time_span_s", ctx.span())
            out += legendre(ctx.tt, (t0, t1), DRIFT_DEGREES) @ coef.reshape(-1, 3)
        return out

    def groups(self, ctx: EffectContext) -> tuple[list[Group], str | None]:
        out = []
        for c in (c for c in ctx.aux if c.startswith("temp_")):
            theta = ctx.aux[c] - ctx.aux[c][0]
            out.append(Group(self.name, c, _body_columns(theta[:, None]),
                             [f"({c}−{c}(t0))·e_{a}" for a in _AXES],
                             lambda b: {"k_nt_per_unit": b.tolist()}))  # fmt: skip
        span = ctx.span()
        cols = _body_columns(legendre(ctx.tt, span, DRIFT_DEGREES))
        labels = [f"P{d}(t)·e_{a}" for d in DRIFT_DEGREES for a in _AXES]
        to_params = lambda b: {"legendre_body_nt": b.tolist(), "time_span_s": list(span)}  # noqa: E731
        out.append(Group(self.name, None, cols, labels, to_params))
        return out, None


class InducedSecondOrder(Effect):
    name = "induced_second_order"
    description = "field quadratic in the body-frame Earth field: Σ c_ijk T_j T_k / 50 000 nT"
    parameter_sizes = MappingProxyType({"coefficients": 18})

    @staticmethod
    def _quadratic(t_b: np.ndarray) -> np.ndarray:
        return np.column_stack([t_b[:, j] * t_b[:, k] for j, k in _PAIRS]) / FIELD_SCALE_NT

    def simulate(
        self, ctx: EffectContext, channel: str | None, params: dict[str, Any]
    ) -> np.ndarray:
        c = _vec(params, "coefficients", 18)
        if c is None:
            return np.zeros((ctx.n, 3))
        return self._quadratic(ctx.t_b) @ c.reshape(3, 6).T

    def groups(self, ctx: EffectContext) -> tuple[list[Group], str | None]:
        q = self._quadratic(ctx.t_b)  # (n, 6)
        cols = np.zeros((ctx.n, 3, 3, 6))
        for i in range(3):
            cols[:, i, i, :] = q
        names = [f"T{_AXES[j]}T{_AXES[k]}" for j, k in _PAIRS]
        labels = [f"{nm}/5e4·e_{a}" for a in _AXES for nm in names]
        return [Group(self.name, None, cols.reshape(ctx.n, 3, 18), labels,
                      lambda b: {"coefficients": b.tolist()})], None  # fmt: skip


class AltitudeGradient(Effect):
    name = "altitude_gradient"
    description = "field changing linearly with altitude, fixed in the navigation frame: g (h − h0)"
    parameter_sizes = MappingProxyType({"gradient_ned_nt_per_m": 3, "reference_alt_m": 0})

    def simulate(
        self, ctx: EffectContext, channel: str | None, params: dict[str, Any]
    ) -> np.ndarray:
        from aeromag_env.geo.frames import nav_to_body

        g = _vec(params, "gradient_ned_nt_per_m", 3)
        if g is None:
            return np.zeros((ctx.n, 3))
        h0 = float(params.get("reference_alt_m", 0.0))
        return nav_to_body(ctx.c_nb, (ctx.alt - h0)[:, None] * g)

    def groups(self, ctx: EffectContext) -> tuple[list[Group], str | None]:
        if not np.all(np.isfinite(ctx.alt)):
            return [], "no finite altitude channel"
        h0 = float(np.mean(ctx.alt))
        cols = _nav_columns(ctx, (ctx.alt - h0)[:, None])
        to_params = lambda b: {"gradient_ned_nt_per_m": b.tolist(), "reference_alt_m": h0}  # noqa: E731
        return [Group(self.name, None, cols, [f"(h−h0)·C_bn e_{a}" for a in _NED], to_params)], None


class EddyTimeConstant(Effect):
    name = "eddy_time_constant"
    description = (
        "eddy field that follows Ṫ through a first-order lag: B_e (L_τ Ṫ − Ṫ) ≈ −τ B_e T̈ "
        "(the instantaneous part B_e Ṫ is the base model's)"
    )
    parameter_sizes = MappingProxyType({"tau_s": 0, "eddy_s": 9})

    @staticmethod
    def _lagged_rate(ctx: EffectContext, tau: float) -> np.ndarray:
        dt = float(np.median(np.diff(ctx.tt)))
        return first_order_lag(ctx.tdot_b, dt, tau) - ctx.tdot_b

    def simulate(
        self, ctx: EffectContext, channel: str | None, params: dict[str, Any]
    ) -> np.ndarray:
        b = _vec(params, "eddy_s", 9)
        if b is None:
            return np.zeros((ctx.n, 3))
        tau = float(params.get("tau_s", 0.0))
        if tau <= 0:
            raise ConfigError("eddy_time_constant: tau_s must be > 0 with eddy_s")
        return self._lagged_rate(ctx, tau) @ b.reshape(3, 3).T

    def group(self, ctx: EffectContext, tau: float) -> Group:
        rate = self._lagged_rate(ctx, tau)
        cols = np.zeros((ctx.n, 3, 3, 3))
        for i in range(3):
            cols[:, i, i, :] = rate
        labels = [f"(L_τ Ṫ{b} − Ṫ{b})·e_{a}" for a in _AXES for b in _AXES]
        return Group(self.name, None, cols.reshape(ctx.n, 3, 9), labels,
                     lambda b: {"tau_s": tau, "eddy_s": b.tolist()}, tau,
                     lambda v: self.group(ctx, v))  # fmt: skip

    def groups(self, ctx: EffectContext) -> tuple[list[Group], str | None]:
        return [self.group(ctx, tau) for tau in EDDY_TAU_GRID_S], None


class SensorLag(Effect):
    name = "sensor_lag"
    description = (
        "time offset between magnetometer and attitude: S(t − τ) − S(t) ≈ −τ Ṡ + τ²/2 S̈ for the "
        "whole signal S = T + T_p + A T + B Ṫ (+ additive effects); the part −τ (I + A) Ṫ is "
        "absorbed by the eddy matrix, τ²/2 T̈ and the shifted aircraft eddy field −τ B T̈ are not"
    )
    parameter_sizes = MappingProxyType({"lag_s": 0, "field_gain": 0, "signal_gain": 0})

    @staticmethod
    def _shift(ctx: EffectContext, x: np.ndarray, lag: float) -> np.ndarray:
        from scipy.interpolate import CubicSpline

        return (
            np.asarray(CubicSpline(ctx.tt, x, axis=0)(np.clip(ctx.tt - lag, ctx.tt[0], ctx.tt[-1])))
            - x
        )

    def simulate(
        self, ctx: EffectContext, channel: str | None, params: dict[str, Any]
    ) -> np.ndarray:
        lag = float(params.get("lag_s", 0.0))
        if not lag:
            return np.zeros((ctx.n, 3))
        if "field_gain" in params:  # the fitted form: the Earth field shifted, times a gain
            return float(params["field_gain"]) * self._shift(ctx, ctx.t_b, lag)
        if "signal_gain" in params:  # the fitted form: the modelled signal shifted, times a gain
            sig = ctx.t_b if ctx.signal is None else ctx.signal
            return float(params["signal_gain"]) * self._shift(ctx, sig, lag)
        if ctx.signal is None:
            raise ConfigError("sensor_lag: lag_s alone needs the simulated signal")
        return self._shift(ctx, ctx.signal, lag)

    def group(self, ctx: EffectContext, lag: float) -> Group:
        """The Earth field shifted by ``lag`` (one gain); with ``ctx.signal`` (a modelled
        fluxgate signal: Earth field, aircraft field and additive effects) that signal shifted,
        so the lag also moves the aircraft's own eddy field."""
        if ctx.signal is None:
            cols, label, key = self._shift(ctx, ctx.t_b, lag), "T(t − τ) − T(t)", "field_gain"
        else:
            cols, label, key = self._shift(ctx, ctx.signal, lag), "S(t − τ) − S(t)", "signal_gain"
        return Group(self.name, None, cols[:, :, None], [label],
                     lambda b: {"lag_s": lag, key: float(b[0])}, lag,
                     lambda v: self.group(ctx, v))  # fmt: skip

    def groups(self, ctx: EffectContext) -> tuple[list[Group], str | None]:
        return [self.group(ctx, lag) for lag in LAG_GRID_S], None


class _SensorError(Effect):
    """A fluxgate error acting on the signal: ``δ = M S`` for a small constant matrix M."""

    def matrix(self, params: dict[str, Any]) -> np.ndarray:
        raise NotImplementedError

    def simulate(
        self, ctx: EffectContext, channel: str | None, params: dict[str, Any]
    ) -> np.ndarray:
        sig = ctx.t_b if ctx.signal is None else ctx.signal
        return sig @ self.matrix(params).T

    def groups(self, ctx: EffectContext) -> tuple[list[Group], str | None]:
        cols = np.zeros((ctx.n, 3, 3, 3))
        for i in range(3):
            cols[:, i, i, :] = ctx.t_b
        labels = [f"T{b}·e_{a}" for a in _AXES for b in _AXES]
        return [Group(self.name, None, cols.reshape(ctx.n, 3, 9), labels, lambda b: {})], None


class FluxgateOffset(Effect):
    name = "fluxgate_offset"
    description = "constant fluxgate offset b"
    absorbed_by = "T_p (permanent field)"
    parameter_sizes = MappingProxyType({"offset_nt": 3})

    def simulate(
        self, ctx: EffectContext, channel: str | None, params: dict[str, Any]
    ) -> np.ndarray:
        b = _vec(params, "offset_nt", 3)
        return np.zeros((ctx.n, 3)) + (0.0 if b is None else b)

    def groups(self, ctx: EffectContext) -> tuple[list[Group], str | None]:
        cols = _body_columns(np.ones((ctx.n, 1)))
        return [Group(self.name, None, cols, [f"e_{a}" for a in _AXES], lambda b: {})], None


class FluxgateScale(_SensorError):
    name = "fluxgate_scale"
    description = "per-axis scale-factor error: S_i ← (1 + s_i) S_i"
    absorbed_by = "A (induced matrix)"
    parameter_sizes = MappingProxyType({"scale": 3})

    def matrix(self, params: dict[str, Any]) -> np.ndarray:
        v = _vec(params, "scale", 3)
        return np.diag(np.zeros(3) if v is None else v)


class FluxgateNonorthogonality(_SensorError):
    name = "fluxgate_nonorthogonality"
    description = "non-orthogonal axes: y and z axes tilted by small angles towards x and y"
    absorbed_by = "A (induced matrix)"
    parameter_sizes = MappingProxyType({"angles_rad": 3})

    def matrix(self, params: dict[str, Any]) -> np.ndarray:
        v = _vec(params, "angles_rad", 3)
        a = np.zeros(3) if v is None else v
        m = np.zeros((3, 3))
        m[1, 0], m[2, 0], m[2, 1] = a
        return m


class Misalignment(_SensorError):
    name = "misalignment"
    description = "constant rotation between the fluxgate and the INS body axes (small angles)"
    absorbed_by = "A (induced matrix)"
    parameter_sizes = MappingProxyType({"angles_rad": 3})

    def matrix(self, params: dict[str, Any]) -> np.ndarray:
        from scipy.spatial.transform import Rotation

        v = _vec(params, "angles_rad", 3)
        a = np.zeros(3) if v is None else v
        return Rotation.from_rotvec(a).as_matrix() - np.eye(3)


#: Every effect by canonical name, identifiable ones first.
EFFECTS: dict[str, Effect] = {
    e.name: e
    for e in (
        OnboardCurrent(), ExternalFieldVariation(), PermanentFieldDrift(), InducedSecondOrder(),
        AltitudeGradient(), EddyTimeConstant(), SensorLag(),
        FluxgateOffset(), FluxgateScale(), FluxgateNonorthogonality(), Misalignment(),
    )
}  # fmt: skip
#: Effects the base model absorbs entirely (never reported as missing).
ABSORBED = tuple(nm for nm, e in EFFECTS.items() if e.absorbed_by)
#: Effects discovery can name.
IDENTIFIABLE = tuple(nm for nm, e in EFFECTS.items() if not e.absorbed_by)
#: Effects acting on the whole signal: applied after the additive ones, in this order.
SIGNAL_EFFECTS = ("fluxgate_scale", "fluxgate_nonorthogonality", "misalignment", "sensor_lag")


def effect(name: str) -> Effect:
    """The effect of that canonical name; unknown names give a one-line error."""
    if name not in EFFECTS:
        raise ConfigError(f"unknown effect {name!r}; valid: {', '.join(EFFECTS)}")
    return EFFECTS[name]


def check_effect_config(cfg: Any) -> None:
    """Validate an :class:`~aeromag_env.simulation.config.EffectConfig` (name, channel,
    parameters)."""
    effect(cfg.name).check(cfg.channel, cfg.parameters)


def simulate_effects(ctx: EffectContext, configs: tuple[Any, ...]) -> np.ndarray:
    """Sum of the configured effects' fields (n, 3) [nT]: additive effects first, then the
    signal effects (sensor errors, lag) on the signal including them."""
    base = ctx.signal if ctx.signal is not None else ctx.t_b
    additive = [c for c in configs if c.name not in SIGNAL_EFFECTS]
    signal_fx = sorted((c for c in configs if c.name in SIGNAL_EFFECTS),
                       key=lambda c: SIGNAL_EFFECTS.index(c.name))  # fmt: skip
    total = np.zeros((ctx.n, 3))
    for c in additive:
        total += effect(c.name).simulate(ctx, c.channel, c.parameters)
    for c in signal_fx:
        ctx_sig = dataclasses.replace(ctx, signal=base + total)
        total += effect(c.name).simulate(ctx_sig, c.channel, c.parameters)
    return total
