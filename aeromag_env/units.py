"""Units and frames used everywhere in ``aeromag_env`` (the one place they are stated).

Units
-----
* magnetic field [nT]; field rates [nT/s]; variances [nT²]
* time [s]; sample rate [Hz]
* angles [rad] inside the code; degrees only at file and command-line boundaries
  (flight files store ``lat``, ``lon``, ``ins_roll``, ``ins_pitch``, ``ins_yaw`` in degrees)
* angular rates [rad/s]; altitude [m] above the WGS84 ellipsoid; speed [m/s]
* induced coefficients (matrix ``A``) are dimensionless; eddy coefficients (matrix ``B``) [s]

Frames
------
* navigation frame: NED (north, east, down)
* body frame: FRD (x forward, y right wing, z down)
* Euler angles: aerospace ZYX sequence — yaw ψ (clockwise from north), pitch θ (nose up +),
  roll φ (right wing down +). This is also the SGL ``ins_*`` convention.
* ``C_nb`` rotates body → NED; the body-frame field is ``T_b = C_nb.T @ T_n``.

Array shapes
------------
Time first: scalar series ``(n,)``, vector series ``(n, 3)``, rotation-matrix series ``(n, 3, 3)``.

Randomness
----------
Only through a ``numpy.random.Generator`` passed as ``rng``; nothing touches global state.
"""

from __future__ import annotations

#: Mean Earth-field magnitude used to scale Tolles–Lawson induced and eddy terms [nT]
#: (MagNav.jl convention).
BT_SCALE_NT = 50_000.0

#: Standard gravity [m/s²].
GRAVITY_M_S2 = 9.80665

#: WGS84 semi-major axis [m] and first eccentricity squared [-].
WGS84_A_M = 6_378_137.0
WGS84_E2 = 6.694_379_990_14e-3

#: Plausible range of the Earth's total field at aircraft altitudes [nT].
EARTH_FIELD_RANGE_NT = (15_000.0, 75_000.0)
