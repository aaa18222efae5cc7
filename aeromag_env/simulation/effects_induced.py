"""Higher-order aircraft fields: induced magnetisation quadratic in the Earth field and eddy
currents decaying with a time constant."""

from __future__ import annotations

from types import MappingProxyType
from typing import Any

import numpy as np

from aeromag_env.errors import ConfigError
from aeromag_env.geo.earth import first_order_lag
from aeromag_env.simulation.effects_base import (
    AXES,
    EDDY_TAU_GRID_S,
    FIELD_SCALE_NT,
    Effect,
    EffectContext,
    Group,
    vector_parameter,
)

#: Index pairs (j, k) of the quadratic terms T_j T_k, in coefficient order.
_PAIRS = ((0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2))


class InducedSecondOrder(Effect):
    name = "induced_second_order"
    description = "field quadratic in the body-frame Earth field: Σ c_ijk T_j T_k / 50 000 nT"
    parameter_sizes = MappingProxyType({"coefficients": 18})
    strength = ("coefficients",)

    @staticmethod
    def _quadratic(t_b: np.ndarray) -> np.ndarray:
        return np.column_stack([t_b[:, j] * t_b[:, k] for j, k in _PAIRS]) / FIELD_SCALE_NT

    def simulate(
        self, ctx: EffectContext, channel: str | None, params: dict[str, Any]
    ) -> np.ndarray:
        c = vector_parameter(params, "coefficients", 18)
        if c is None:
            return np.zeros((ctx.n, 3))
        return self._quadratic(ctx.t_b) @ c.reshape(3, 6).T

    def groups(self, ctx: EffectContext) -> tuple[list[Group], str | None]:
        q = self._quadratic(ctx.t_b)  # (n, 6)
        cols = np.zeros((ctx.n, 3, 3, 6))
        for i in range(3):
            cols[:, i, i, :] = q
        names = [f"T{AXES[j]}T{AXES[k]}" for j, k in _PAIRS]
        labels = [f"{nm}/5e4·e_{a}" for a in AXES for nm in names]
        return [
            Group(
                self.name,
                None,
                cols.reshape(ctx.n, 3, 18),
                labels,
                lambda b: {"coefficients": b.tolist()},
            )
        ], None


class EddyTimeConstant(Effect):
    name = "eddy_time_constant"
    description = (
        "eddy field that follows Ṫ through a first-order lag: B_e (L_τ Ṫ − Ṫ) ≈ −τ B_e T̈ "
        "(the instantaneous part B_e Ṫ is the base model's)"
    )
    parameter_sizes = MappingProxyType({"tau_s": 0, "eddy_s": 9})
    strength = ("eddy_s",)

    @staticmethod
    def _lagged_rate(ctx: EffectContext, tau: float) -> np.ndarray:
        dt = float(np.median(np.diff(ctx.tt)))
        return first_order_lag(ctx.tdot_b, dt, tau) - ctx.tdot_b

    def simulate(
        self, ctx: EffectContext, channel: str | None, params: dict[str, Any]
    ) -> np.ndarray:
        b = vector_parameter(params, "eddy_s", 9)
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
        labels = [f"(L_τ Ṫ{b} − Ṫ{b})·e_{a}" for a in AXES for b in AXES]
        return Group(
            self.name,
            None,
            cols.reshape(ctx.n, 3, 9),
            labels,
            lambda b: {"tau_s": tau, "eddy_s": b.tolist()},
            tau,
            lambda v: self.group(ctx, v),
        )

    def groups(self, ctx: EffectContext) -> tuple[list[Group], str | None]:
        return [self.group(ctx, tau) for tau in EDDY_TAU_GRID_S], None
