"""Candidate effects: which regressor groups of the effects library are tested, which are absorbed.

Every effect of :mod:`aeromag_env.simulation.effects` builds its regressor groups from the
channels present (one group per auxiliary channel for ``onboard_current``); an effect whose
channels are missing is skipped, with its reason. A group whose part outside the base
regressors' span is below :data:`ABSORBED_FRACTION` of its variance is *absorbed*
(Frisch–Waugh–Lovell) and never tested or named; effects marked ``absorbed_by`` in the library
(offset, scale, non-orthogonality, misalignment) are always such groups.

With ground separation (:mod:`~aeromag_env.discovery.ground`), every group is taken off the
ground's span first; a group the ground takes (almost) entirely is absorbed by it, and one with
less than :data:`~aeromag_env.discovery.ground.SEPARABLE_FRACTION` left is tested but listed as
not separable from geology on this flight.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from aeromag_env.discovery.base_model import BaseSpan
from aeromag_env.discovery.ground import SEPARABLE_FRACTION, GroundReference
from aeromag_env.discovery.regressors import compact_group, spline_group
from aeromag_env.simulation.effects import EFFECTS, EffectContext, Group

#: A group with less of its variance outside the base span than this is absorbed.
ABSORBED_FRACTION = 1e-3


@dataclass
class Candidates:
    """The effects library's groups for one flight, sorted by verdict.

    Attributes
    ----------
    groups : list of Group
        Groups to test (profiled families have one group per grid value).
    fractions : list of float
        Identifiable fraction of each group in ``groups`` (outside the base span).
    skipped : list of dict
        ``name`` and ``reason`` of effects the file lacks channels for.
    absorbed : list of dict
        ``name``, ``channel``, ``identifiable_fraction`` and ``absorbed_by`` of absorbed groups.
    inseparable : list of dict
        With ground separation: ``name``, ``channel`` and ``kept_by_ground`` (the share of the
        group's variance outside the ground span) of groups below
        :data:`~aeromag_env.discovery.ground.SEPARABLE_FRACTION`, one per family.
    """

    groups: list[Group] = field(default_factory=list)
    fractions: list[float] = field(default_factory=list)
    skipped: list[dict[str, str]] = field(default_factory=list)
    absorbed: list[dict[str, Any]] = field(default_factory=list)
    inseparable: list[dict[str, Any]] = field(default_factory=list)


def candidate_groups(
    ctx: EffectContext, span: BaseSpan, ground: GroundReference | None = None
) -> Candidates:
    """Build every effect's groups from the channels present and set the absorbed ones apart.

    Parameters
    ----------
    ctx : EffectContext
        The flight's model field context (:attr:`PreparedFlight.ctx
        <aeromag_env.discovery.preparation.PreparedFlight.ctx>`).
    span : BaseSpan
        The base regressors' span on the calibration rows (off the ground, with ``ground``).
    ground : GroundReference or None
        The ground's span, with ground separation: each group is taken off it.

    Returns
    -------
    Candidates
        Groups to test with their identifiable fractions, skipped effects, absorbed groups;
        in the order of :data:`~aeromag_env.simulation.effects.EFFECTS`.
    """
    out = Candidates()
    for name, eff in EFFECTS.items():
        found, why = _groups(name, ctx, ground)
        if why:
            out.skipped.append({"name": name, "reason": why})
        for g in found:
            kept = 1.0
            if ground is not None and not eff.absorbed_by:
                g, kept = ground.separate(g, span.rows)
            frac = span.identifiable_fraction(g.columns) * kept
            if eff.absorbed_by or frac < ABSORBED_FRACTION:
                by = "the base model" + ("" if ground is None else " and the ground reference")
                by = ("the ground reference" if kept < ABSORBED_FRACTION else by) + " here"
                out.absorbed.append(
                    {
                        "name": name,
                        "channel": g.channel,
                        "identifiable_fraction": frac,
                        "absorbed_by": eff.absorbed_by or by,
                    }
                )
                continue
            if kept < SEPARABLE_FRACTION and not any(
                d["name"] == name and d["channel"] == g.channel for d in out.inseparable
            ):
                out.inseparable.append({"name": name, "channel": g.channel, "kept_by_ground": kept})
            out.groups.append(g)
            out.fractions.append(frac)
    return out


def _groups(
    name: str, ctx: EffectContext, ground: GroundReference | None
) -> tuple[list[Group], str | None]:
    """Effect ``name``'s candidate groups from the channels present, and why none (or None), held
    compact (:mod:`~aeromag_env.discovery.regressors`: the external field's B-splines sparse,
    one-axis groups by axis) unless the ground is separated (off the ground they are dense)."""
    if ground is not None:  # off the ground no group keeps a compact form
        return EFFECTS[name].groups(ctx)
    if name == "external_field_variation":
        return [spline_group(ctx)], None
    found, why = EFFECTS[name].groups(ctx)
    return [compact_group(g) for g in found], why
