"""
Discover a missing effect
=========================

The compensator's model of the aircraft (a permanent, an induced and an eddy-current field) does
not know every physical effect. Here a flight is simulated with one effect the model lacks — the
field of a pump's current, recorded in an auxiliary channel ``cur_pump`` — and the discrepancy
workflow names it from the data alone: it fits the model, tests a library of candidate effects
against the residual and keeps those that explain it on held-out data.
"""

# %%
# A flight with an effect the model does not have
# -----------------------------------------------
# ``onboard_current`` couples the channel to the fluxgate with a field of a few nT per ampere
# per axis (body frame).
from dataclasses import replace

import matplotlib.pyplot as plt
import numpy as np

import aeromag_env as am
from aeromag_env.simulation.config import AuxChannelConfig, EffectConfig

config = replace(
    am.preset("nominal"),
    aux_channels=(AuxChannelConfig(name="cur_pump", level=2.0, period_s=40.0),),
    effects=(
        EffectConfig(
            name="onboard_current",
            channel="cur_pump",
            parameters={"k_nt_per_unit": [3.0, -2.0, 1.5]},
        ),
    ),
)
flight = am.simulate_flight(config, rng=11)

# %%
# Run the workflow
# ----------------
# ``truth_*`` fields are never read: the same call works on a measured flight.
found = am.discover(flight)
for effect in found.report["missing_effects"]:
    print(effect["name"], "driven by", effect["channel"])
gap = found.report["gap"]
print(f"held-out gap {gap['rms_before_nt']:.3g} nT -> {gap['rms_after_nt']:.3g} nT")

# %%
# The residual before and after the named effect
# ----------------------------------------------
# The residual of the fitted model (the z axis) follows the pump's switching until the effect is
# added.
t = found.series["tt"] - found.series["tt"][0]
fig, (ax0, ax1) = plt.subplots(2, 1, figsize=(8, 5), sharex=True, layout="constrained")
ax0.plot(t, flight["cur_pump"], lw=0.7, color="tab:gray")
ax0.set(ylabel="cur_pump [A]")
ax1.plot(t, found.series["residual_before"][:, 2], lw=0.5, label="model without the effect")
ax1.plot(t, found.series["residual_after"][:, 2], lw=0.5, label="with the named effect")
ax1.set(
    xlabel="time [s]",
    ylabel="residual, z [nT]",
    ylim=np.nanpercentile(found.series["residual_before"][:, 2], [0.5, 99.5]),
)
ax1.legend(loc="upper right")
plt.show()
