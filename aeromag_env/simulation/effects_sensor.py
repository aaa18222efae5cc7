"""Sensor-side effects: a time lag between magnetometer and attitude, and the fluxgate's own
errors (offset, scale, non-orthogonality, misalignment to the INS axes), the last four absorbed
by the base model."""

from __future__ import annotations

from types import MappingProxyType
from typing import Any

import numpy as np

from aeromag_env.errors import ConfigError
from aeromag_env.simulation.effects_base import (
    AXES,
    LAG_GRID_S,
    Effect,
    EffectContext,
    Group,
    body_columns,
    vector_parameter,
)


class SensorLag(Effect):
    name = "sensor_lag"
    description = (
        "time offset between magnetometer and attitude: S(t − τ) − S(t) ≈ −τ Ṡ + τ²/2 S̈ for the "
        "whole signal S = T + T_p + A T + B Ṫ (+ additive effects); the part −τ (I + A) Ṫ is "
        "absorbed by the eddy matrix, τ²/2 T̈ and the shifted aircraft eddy field −τ B T̈ are not"
    )
    parameter_sizes = MappingProxyType({"lag_s": 0, "field_gain": 0, "signal_gain": 0})
    strength = ("lag_s",)

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
        return Group(
            self.name,
            None,
            cols[:, :, None],
            [label],
            lambda b: {"lag_s": lag, key: float(b[0])},
            lag,
            lambda v: self.group(ctx, v),
        )

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
        labels = [f"T{b}·e_{a}" for a in AXES for b in AXES]
        return [Group(self.name, None, cols.reshape(ctx.n, 3, 9), labels, lambda b: {})], None


class FluxgateOffset(Effect):
    name = "fluxgate_offset"
    description = "constant fluxgate offset b"
    absorbed_by = "T_p (permanent field)"
    parameter_sizes = MappingProxyType({"offset_nt": 3})
    strength = ("offset_nt",)

    def simulate(
        self, ctx: EffectContext, channel: str | None, params: dict[str, Any]
    ) -> np.ndarray:
        b = vector_parameter(params, "offset_nt", 3)
        return np.zeros((ctx.n, 3)) + (0.0 if b is None else b)

    def groups(self, ctx: EffectContext) -> tuple[list[Group], str | None]:
        cols = body_columns(np.ones((ctx.n, 1)))
        return [Group(self.name, None, cols, [f"e_{a}" for a in AXES], lambda b: {})], None


class FluxgateScale(_SensorError):
    name = "fluxgate_scale"
    description = "per-axis scale-factor error: S_i ← (1 + s_i) S_i"
    absorbed_by = "A (induced matrix)"
    parameter_sizes = MappingProxyType({"scale": 3})
    strength = ("scale",)

    def matrix(self, params: dict[str, Any]) -> np.ndarray:
        v = vector_parameter(params, "scale", 3)
        return np.diag(np.zeros(3) if v is None else v)


class FluxgateNonorthogonality(_SensorError):
    name = "fluxgate_nonorthogonality"
    description = "non-orthogonal axes: y and z axes tilted by small angles towards x and y"
    absorbed_by = "A (induced matrix)"
    parameter_sizes = MappingProxyType({"angles_rad": 3})
    strength = ("angles_rad",)

    def matrix(self, params: dict[str, Any]) -> np.ndarray:
        v = vector_parameter(params, "angles_rad", 3)
        a = np.zeros(3) if v is None else v
        m = np.zeros((3, 3))
        m[1, 0], m[2, 0], m[2, 1] = a
        return m


class Misalignment(_SensorError):
    name = "misalignment"
    description = "constant rotation between the fluxgate and the INS body axes (small angles)"
    absorbed_by = "A (induced matrix)"
    parameter_sizes = MappingProxyType({"angles_rad": 3})
    strength = ("angles_rad",)

    def matrix(self, params: dict[str, Any]) -> np.ndarray:
        from scipy.spatial.transform import Rotation

        v = vector_parameter(params, "angles_rad", 3)
        a = np.zeros(3) if v is None else v
        return Rotation.from_rotvec(a).as_matrix() - np.eye(3)
