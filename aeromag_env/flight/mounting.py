"""Fluxgate mounting: the rotation from the aircraft's body frame to a fluxgate's own axes.

Real fluxgates are not mounted along the body axes (in the public SGL flights ``flux_a`` is close
to an axis swap and ``flux_b`` sits about 45° off), and a vector compensator that takes the sensor
axes for body axes fits the rotation as "induced field": tens of thousands of nT of error. The
rotation is recoverable from the data, since a fluxgate reads the Earth's field plus a small
interference::

    m_s(k) ≈ R (T_b(k) + ΔT(k)),    T_b(k) = C_nb(k)ᵀ T_igrf(k)

with ``R`` (3×3, proper orthogonal) the mount, body → sensor. Minimising ``Σ |m_s − R T_b − c|²``
over ``R`` and a constant ``c`` (the permanent field, in sensor axes) is Wahba's problem on the
centred series, solved by the SVD of their cross-covariance ``B = Σ (m_s − m̄)(T_b − T̄)ᵀ``
(Kabsch; scipy's ``Rotation.align_vectors``).

A rotation is indistinguishable from the antisymmetric part of the induced matrix ``A`` (a small
``R (I + A)`` has many factorisations), so the estimate carries that part of ``A`` with it; the
compensated field is the same, and the compensator's ``A`` is then the symmetric rest.

The fit needs attitude variation (the calibration box gives plenty; a straight survey line does
not): :attr:`Mount.conditioning` is the smallest over the largest singular value of ``B``, and a
fit below :data:`MIN_CONDITIONING` is refused.

Which mount a compensation uses, and mount files: :mod:`aeromag_env.flight.mount_choice`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from aeromag_env.errors import AeromagError
from aeromag_env.flight.data import Flight
from aeromag_env.flight.earth_model import earth_model_ned
from aeromag_env.geo.frames import dcm_from_euler, euler_from_dcm, nav_to_body

#: Smallest usable ratio of the cross-covariance's singular values (attitude variation).
MIN_CONDITIONING = 1e-3
#: An assumed mount further than this from the estimated one is warned about [deg].
WARN_ANGLE_DEG = 5.0
#: Fewest valid samples for a mount fit.
MIN_SAMPLES = 50


@dataclass(frozen=True)
class Mount:
    """A fluxgate mount: ``m_sensor = rotation @ m_body``.

    Attributes
    ----------
    rotation : ndarray, shape (3, 3)
        Body → sensor rotation (proper orthogonal).
    residual_nt : float
        RMS misfit ``|m_s − R T_b − c|`` over the samples used [nT] (NaN if not fitted).
    conditioning : float
        Smallest over largest singular value of the cross-covariance [-] (NaN if not fitted).
    samples : int
        Samples the fit used.
    source : str
        ``identity``, ``estimated`` or ``file``.
    """

    rotation: np.ndarray
    residual_nt: float = math.nan
    conditioning: float = math.nan
    samples: int = 0
    source: str = "identity"

    @classmethod
    def identity(cls) -> Mount:
        """The body-aligned mount (sensor axes = body axes)."""
        return cls(rotation=np.eye(3))

    @classmethod
    def from_angles_deg(cls, roll: float, pitch: float, yaw: float) -> Mount:
        """The mount whose sensor frame has ZYX angles ``roll, pitch, yaw`` [deg] in body axes."""
        c = dcm_from_euler(*(np.deg2rad([v]) for v in (roll, pitch, yaw)))[0]
        return cls(rotation=c.T, source="file")

    def angles_deg(self) -> tuple[float, float, float]:
        """ZYX angles (roll, pitch, yaw) of the sensor frame in body axes [deg]."""
        roll, pitch, yaw = euler_from_dcm(self.rotation.T[None])
        return float(np.rad2deg(roll[0])), float(np.rad2deg(pitch[0])), float(np.rad2deg(yaw[0]))

    def to_body(self, m_sensor: np.ndarray) -> np.ndarray:
        """Sensor-axis vectors (n, 3) → body axes (n, 3): ``m_b = Rᵀ m_s`` per row."""
        return np.asarray(m_sensor) @ self.rotation

    def angle_to_deg(self, other: Mount) -> float:
        """The angle of the rotation between two mounts [deg]."""
        cos = (np.trace(self.rotation.T @ other.rotation) - 1.0) / 2.0
        return float(np.rad2deg(np.arccos(np.clip(cos, -1.0, 1.0))))

    def to_dict(self) -> dict[str, object]:
        """JSON-ready summary (angles in degrees)."""
        roll, pitch, yaw = self.angles_deg()
        return {
            "source": self.source,
            "roll_deg": roll,
            "pitch_deg": pitch,
            "yaw_deg": yaw,
            "rotation": self.rotation.tolist(),
            "residual_nt": None if math.isnan(self.residual_nt) else self.residual_nt,
            "conditioning": None if math.isnan(self.conditioning) else self.conditioning,
            "samples": self.samples,
        }


def solve_wahba(m_sensor: np.ndarray, t_body: np.ndarray) -> Mount:
    """The mount minimising ``Σ |m_s − R T_b − c|²`` over rotations ``R`` and a constant ``c``.

    Parameters
    ----------
    m_sensor : ndarray, shape (n, 3)
        Fluxgate readings in its own axes [nT]; rows with a non-finite value are skipped.
    t_body : ndarray, shape (n, 3)
        Model Earth field in body axes [nT], same rows.

    Returns
    -------
    Mount
        ``source="estimated"``, with its residual, conditioning and sample count.
    """
    ok = np.isfinite(m_sensor).all(axis=1) & np.isfinite(t_body).all(axis=1)
    n = int(ok.sum())
    if n < MIN_SAMPLES:
        raise AeromagError(
            f"cannot estimate the fluxgate mount: {n} valid samples (need ≥ {MIN_SAMPLES})"
        )
    m = m_sensor[ok] - m_sensor[ok].mean(axis=0)
    t = t_body[ok] - t_body[ok].mean(axis=0)
    s = np.linalg.svd(m.T @ t, compute_uv=False)  # of the cross-covariance B = Σ m tᵀ
    conditioning = float(s[-1] / s[0]) if s[0] > 0 else 0.0
    if conditioning < MIN_CONDITIONING:
        raise AeromagError(
            f"cannot estimate the fluxgate mount: too little attitude variation "
            f"(conditioning {conditioning:.1e} < {MIN_CONDITIONING:g}); fly or select the "
            "calibration box, or give the mount with --mount FILE"
        )
    from scipy.spatial.transform import Rotation  # lazy: keeps `import aeromag_env` light

    rotation = Rotation.align_vectors(m, t)[0].as_matrix()  # Kabsch: min Σ |m − R t|²
    misfit = m - t @ rotation.T
    residual = float(np.sqrt(np.mean(np.sum(misfit**2, axis=1))))
    return Mount(rotation, residual, conditioning, n, "estimated")


def mount_residual_nt(mount: Mount, m_sensor: np.ndarray, t_body: np.ndarray) -> float:
    """RMS misfit ``|m_s − R T_b − c|`` of a given mount, ``c`` the best constant [nT]."""
    ok = np.isfinite(m_sensor).all(axis=1) & np.isfinite(t_body).all(axis=1)
    misfit = m_sensor[ok] - t_body[ok] @ mount.rotation.T
    misfit -= misfit.mean(axis=0)
    return float(np.sqrt(np.mean(np.sum(misfit**2, axis=1))))


def body_field(flight: Flight) -> np.ndarray:
    """Model Earth field in body axes (n, 3) [nT] from position, date and attitude."""
    return nav_to_body(dcm_from_euler(*flight.attitude_rad()), earth_model_ned(flight))


def estimate_mount(flight: Flight, flux: str, mask: np.ndarray | None = None) -> Mount:
    """The mount of fluxgate ``flux`` (e.g. ``"flux_a"``) from the flight itself.

    ``mask`` (n,) bool restricts the fit (e.g. to the calibration box); samples with a
    non-finite reading, attitude or position are skipped.
    """
    m, t = flight.vector(flux), body_field(flight)
    if mask is not None:
        m, t = m[mask], t[mask]
    return solve_wahba(m, t)


def mount_warning(assumed: Mount, estimated: Mount, flux: str) -> str | None:
    """A one-line warning when the assumed mount is far from what the data indicate, else None."""
    angle = assumed.angle_to_deg(estimated)
    if angle <= WARN_ANGLE_DEG:
        return None
    return (
        f"{flux}: the assumed mount ({assumed.source}) is {angle:.1f}° from the one the data "
        f"indicate (roll/pitch/yaw {', '.join(f'{v:.1f}' for v in estimated.angles_deg())}°, "
        f"residual {estimated.residual_nt:.0f} nT); the vector methods will fit the rotation "
        "as induced field"
    )
