"""On-board effects: fields of the aircraft's currents (auxiliary current/voltage channels) and
the temperature-driven drift of its permanent field."""

from __future__ import annotations

from types import MappingProxyType
from typing import Any

import numpy as np

from aeromag_env.errors import ConfigError
from aeromag_env.simulation.effects_base import (
    AXES,
    DRIFT_DEGREES,
    Effect,
    EffectContext,
    Group,
    body_columns,
    legendre,
    vector_parameter,
)


class OnboardCurrent(Effect):
    name = "onboard_current"
    description = "field proportional to an auxiliary current/voltage channel: k · I(t)"
    parameter_sizes = MappingProxyType({"k_nt_per_unit": 3})
    strength = ("k_nt_per_unit",)
    channel_prefixes = ("cur_", "vol_")

    def simulate(
        self, ctx: EffectContext, channel: str | None, params: dict[str, Any]
    ) -> np.ndarray:
        k = vector_parameter(params, "k_nt_per_unit", 3)
        return np.zeros((ctx.n, 3)) if k is None else self._channel(ctx, channel)[:, None] * k

    def groups(self, ctx: EffectContext) -> tuple[list[Group], str | None]:
        chans = [c for c in ctx.aux if c.startswith(self.channel_prefixes)]
        out = [
            Group(
                self.name,
                c,
                body_columns(ctx.aux[c][:, None]),
                [f"{c}·e_{a}" for a in AXES],
                lambda b: {"k_nt_per_unit": b.tolist()},
            )
            for c in chans
        ]
        return out, None if chans else "no cur_* or vol_* channel in the file"


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
    strength = ("k_nt_per_unit", "legendre_body_nt")
    channel_prefixes = ("temp_",)
    channel_optional = True

    def simulate(
        self, ctx: EffectContext, channel: str | None, params: dict[str, Any]
    ) -> np.ndarray:
        out = np.zeros((ctx.n, 3))
        k = vector_parameter(params, "k_nt_per_unit", 3)
        if k is not None:
            if channel is None:
                raise ConfigError("permanent_field_drift: k_nt_per_unit needs a temp_* channel")
            theta = self._channel(ctx, channel)
            out += (theta - theta[0])[:, None] * k
        coef = vector_parameter(params, "legendre_body_nt", 3 * len(DRIFT_DEGREES))
        if coef is not None:
            t0, t1 = params.get("time_span_s", ctx.span())
            out += legendre(ctx.tt, (t0, t1), DRIFT_DEGREES) @ coef.reshape(-1, 3)
        return out

    def groups(self, ctx: EffectContext) -> tuple[list[Group], str | None]:
        out = []
        for c in (c for c in ctx.aux if c.startswith("temp_")):
            theta = ctx.aux[c] - ctx.aux[c][0]
            out.append(
                Group(
                    self.name,
                    c,
                    body_columns(theta[:, None]),
                    [f"({c}−{c}(t0))·e_{a}" for a in AXES],
                    lambda b: {"k_nt_per_unit": b.tolist()},
                )
            )
        span = ctx.span()
        cols = body_columns(legendre(ctx.tt, span, DRIFT_DEGREES))
        labels = [f"P{d}(t)·e_{a}" for d in DRIFT_DEGREES for a in AXES]
        to_params = lambda b: {"legendre_body_nt": b.tolist(), "time_span_s": list(span)}  # noqa: E731
        out.append(Group(self.name, None, cols, labels, to_params))
        return out, None
