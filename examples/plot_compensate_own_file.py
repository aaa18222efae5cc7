"""
Compensate your own flight file
===============================

From a flight file on disk to a compensated field: read it (HDF5, CSV, Geosoft XYZ or MATLAB
``.mat``; the format is found from the content), compensate the fluxgate with the paper's fuzzy
adaptive Kalman filter and the scalar magnetometer with Tolles–Lawson, score both and plot them.

There is no flight file in the package, so this example first simulates one and writes it
as Geosoft XYZ, the way a survey company delivers it; replace ``path`` with your own file.
"""

# %%
# A flight file to start from
# ---------------------------
# A short calibration flight (boxes of roll, pitch and yaw manoeuvres), written as XYZ. Our
# simulated files carry the truth (``truth_*`` fields) so that we can score the compensation.
import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

import aeromag_env as am

folder = Path(tempfile.mkdtemp())
path = folder / "my_flight.xyz"
am.write_flight(am.simulate_flight(am.preset("nominal"), rng=7), path)
print(path.stat().st_size // 1024, "KiB of Geosoft XYZ")

# %%
# Read it
# -------
# The reader renames the columns it knows (``UNCOMPMAG1`` → ``mag_1_uc``, ``FLUXA_X`` →
# ``flux_a_x``…; see the flight-file reference) and keeps the originals in ``attrs``.
flight = am.read_flight(path)
print(flight.n, "samples at", flight.sample_rate_hz, "Hz")
print("fluxgate:", [n for n in flight.names if n.startswith("flux_a")])

# %%
# Compensate: the paper's filter on the fluxgate, Tolles–Lawson on the scalar
# ---------------------------------------------------------------------------
vector = am.compensate_vector(flight, "fakf")
scalar = am.compensate_scalar(flight, "flux_a", "mag_1_uc", am.TollesLawson())
for comp in (vector, scalar):
    metrics = am.score(flight, comp)
    print(
        f"{comp.method:5s} RMSE {metrics['compensation_rmse_nt']:.3g} nT, "
        f"improvement ratio {metrics['improvement_ratio']:.3g}"
    )

# %%
# Look at it
# ----------
# The total field before and after each compensation, about its mean.
t = flight["tt"] - flight["tt"][0]
fig, ax = plt.subplots(figsize=(8, 4), layout="constrained")
ax.plot(t, scalar.total_before - np.nanmean(scalar.total_before), lw=0.6, label="uncompensated")
ax.plot(t, vector.total_after - np.nanmean(vector.total_after), lw=0.6, label="fuzzy adaptive KF")
ax.plot(t, scalar.total_after - np.nanmean(scalar.total_after), lw=0.6, label="Tolles–Lawson")
ax.set(xlabel="time [s]", ylabel="total field − mean [nT]", title=path.name)
ax.legend(loc="upper right")
plt.show()

# %%
# Write the result
# ----------------
# The compensated channels join the flight's own fields; any of the four formats works.
out = am.Flight({**flight.fields, **vector.fields, **scalar.fields}, flight.attrs)
am.write_flight(out, folder / "compensated.h5")
print(sorted(set(out.names) - set(flight.names)))
