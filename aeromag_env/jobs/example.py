"""A sample survey file, as a contractor delivers it: :func:`example`, the job of ``aeromag
example``.

No real survey file may be shipped (the public SGL flights are under an acceptable-use
agreement), and a simulator's own file is too tidy to show what reading a real one takes. So this
writes what the guide to your own flight files (docs/howto/own-flight-files.md) walks through: a
simulated calibration box and six survey lines (the ``nominal`` preset, seed :data:`SEED`) with
Geosoft column names (``UNCOMPMAG1``, ``FLUXA_X``, ``ROLL``, ``AZIMUTH``…), no simulator truth
and no attributes, and what real files bring: the fluxgate mounted as an axis swap (sensor x, y,
z = body right, down, forward, as SGL's ``flux_a``), a 30 s logger gap on a survey line, one
1e6 nT spike in the scalar, three missing pitch samples, and the vendor's compensated channel
``COMPMAG1`` (the scalar minus the true interference, plus 0.05 nT of noise). It is the same file,
bit for bit, as ``experiments/own_flight_file.py`` writes.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from aeromag_env.flight.data import Flight, vector_names
from aeromag_env.flight.files import write_flight
from aeromag_env.flight.validation import PathLike
from aeromag_env.simulation.config import preset, with_overrides
from aeromag_env.simulation.simulate import simulate_flight

#: Our names → the Geosoft column names of an SGL-style delivery (the alias table reverses it).
GEOSOFT = {
    "tt": "TIME",
    "line": "LINE",
    "lat": "LAT",
    "lon": "LONG",
    "alt": "UTM-Z",
    "year": "YEAR",
    "doy": "DOY",
    "ins_roll": "ROLL",
    "ins_pitch": "PITCH",
    "ins_yaw": "AZIMUTH",
    "flux_a_x": "FLUXA_X",
    "flux_a_y": "FLUXA_Y",
    "flux_a_z": "FLUXA_Z",
    "mag_1_uc": "UNCOMPMAG1",
    "mag_1_c": "COMPMAG1",
    "diurnal": "DIURNAL",
}
#: Sensor axes = body right, down, forward: m_sensor = AXIS_SWAP @ m_body.
AXIS_SWAP = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]])
#: The simulation seed of the flight (the guide's figures are this flight's).
SEED = 11
#: What the file brings, for the command's line and the guide: the gap [s], the spike's time [s]
#: and size [nT], the first of the three missing pitch samples [s], the vendor's noise [nT].
GAP_S, SPIKE_AT_S, SPIKE_NT, DROPOUT_AT_S, VENDOR_NOISE_NT = (
    (1500.0, 1530.0),
    1700.0,
    1e6,
    1800.0,
    0.05,
)


@dataclass(frozen=True)
class ExampleResult:
    """What :func:`example` wrote: the flight (Geosoft names) and its file."""

    flight: Flight
    path: Path

    def summary(self) -> str:
        """One line for the terminal."""
        return (
            f"wrote {self.path}: {self.flight.n} samples of a simulated calibration box and six "
            "survey lines, as a contractor delivers them (Geosoft names, the fluxgate mounted as "
            "an axis swap, a 30 s gap, one spike, 3 missing pitch samples, the vendor's COMPMAG1)"
        )


def contractor_flight(seed: int = SEED) -> Flight:
    """The simulated flight as a contractor would deliver it (the module's docstring)."""
    cfg = with_overrides(preset("nominal"), {"trajectory.pattern": "calibration+survey"})
    sim = simulate_flight(cfg, rng=seed)
    rng = np.random.default_rng(seed)
    fields = {name: sim[name].copy() for name in GEOSOFT if name in sim}
    swapped = sim.vector("flux_a") @ AXIS_SWAP.T
    fields.update(zip(vector_names("flux_a"), swapped.T, strict=True))
    noise = rng.normal(0, VENDOR_NOISE_NT, sim.n)
    fields["mag_1_c"] = sim["mag_1_uc"] - sim["truth_interf_mag_1"] + noise
    tt = sim.tt
    keep = ~((tt >= GAP_S[0]) & (tt < GAP_S[1]))  # a logger gap on a survey line
    fields["mag_1_uc"][int(np.searchsorted(tt, SPIKE_AT_S))] += SPIKE_NT  # one wild sample
    fields["ins_pitch"][np.searchsorted(tt, DROPOUT_AT_S) + np.arange(3)] = np.nan  # INS dropout
    return Flight({GEOSOFT[k]: v[keep] for k, v in fields.items()}, {})


def example(target: PathLike) -> ExampleResult:
    """Write the sample survey file to ``target`` (its suffix picks the format: ``.xyz``, as a
    contractor delivers it, or ``.h5``, ``.csv``, ``.mat``), as ``aeromag example`` does.

    Raises
    ------
    FlightFileError
        An unknown suffix or a failed write (one line); the file is written atomically.
    """
    flight = contractor_flight()
    return ExampleResult(flight, write_flight(flight, target))
