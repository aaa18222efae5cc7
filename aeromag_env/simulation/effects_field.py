"""Field-side effects: fields fixed in the navigation frame that the aircraft flies through
(an external variation such as the diurnal, an altitude gradient)."""

from __future__ import annotations

from types import MappingProxyType
from typing import Any

import numpy as np

from aeromag_env.errors import ConfigError
from aeromag_env.geo.earth import external_variation_ned
from aeromag_env.simulation.effects_base import (
    NED,
    Effect,
    EffectContext,
    Group,
    nav_columns,
    spline_basis,
    spline_knots,
    vector_parameter,
)


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
    strength = ("offset_ned_nt", "daily_amplitude_nt", "fogm_std_nt", "spline_ned_nt")

    def simulate(
        self, ctx: EffectContext, channel: str | None, params: dict[str, Any]
    ) -> np.ndarray:
        from aeromag_env.geo.frames import nav_to_body

        d_n = np.zeros((ctx.n, 3))
        offset = vector_parameter(params, "offset_ned_nt", 3)
        if offset is not None:
            d_n += offset
        daily, fogm_std = params.get("daily_amplitude_nt", 0.0), params.get("fogm_std_nt", 0.0)
        if daily or fogm_std:
            if ctx.rng is None or ctx.start is None:
                raise ConfigError("external_field_variation: a random variation needs a simulation")
            d_n += external_variation_ned(
                ctx.tt,
                ctx.start,
                float(daily),
                float(fogm_std),
                float(params.get("fogm_tau_s", 600.0)),
                ctx.rng,
                float(params.get("smoothing_s", 60.0)),
            )
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
        cols = nav_columns(ctx, basis)
        labels = [f"N{m}(t)·C_bn e_{a}" for m in range(basis.shape[1]) for a in NED]
        to_params = lambda b: {"spline_ned_nt": b.tolist(), "spline_knots_s": knots.tolist()}  # noqa: E731
        return [Group(self.name, None, cols, labels, to_params)], None


class AltitudeGradient(Effect):
    name = "altitude_gradient"
    description = "field changing linearly with altitude, fixed in the navigation frame: g (h − h0)"
    parameter_sizes = MappingProxyType({"gradient_ned_nt_per_m": 3, "reference_alt_m": 0})
    strength = ("gradient_ned_nt_per_m",)

    def simulate(
        self, ctx: EffectContext, channel: str | None, params: dict[str, Any]
    ) -> np.ndarray:
        from aeromag_env.geo.frames import nav_to_body

        g = vector_parameter(params, "gradient_ned_nt_per_m", 3)
        if g is None:
            return np.zeros((ctx.n, 3))
        h0 = float(params.get("reference_alt_m", 0.0))
        return nav_to_body(ctx.c_nb, (ctx.alt - h0)[:, None] * g)

    def groups(self, ctx: EffectContext) -> tuple[list[Group], str | None]:
        if not np.all(np.isfinite(ctx.alt)):
            return [], "no finite altitude channel"
        h0 = float(np.mean(ctx.alt))
        cols = nav_columns(ctx, (ctx.alt - h0)[:, None])
        to_params = lambda b: {"gradient_ned_nt_per_m": b.tolist(), "reference_alt_m": h0}  # noqa: E731
        return [Group(self.name, None, cols, [f"(h−h0)·C_bn e_{a}" for a in NED], to_params)], None
