"""Which mount a compensation uses for its fluxgate (``--mount auto|identity|FILE``,
:func:`choose_mount`), and mount files (:func:`read_mount_file`). The estimate itself is
:mod:`aeromag_env.flight.mounting`'s.

* ``auto`` (the default) estimates the mount and applies it when it is more than
  :data:`APPLY_ANGLE_DEG` from the body axes; closer than that the body axes are kept. A rotation
  that small is indistinguishable from the antisymmetric part of an induced matrix of a few 1e-3
  (the simulator's 1.5e-3 per element gives estimates of 0.1–0.25° on body-aligned flights); the
  vector methods absorb it either way (the compensated field changes by < 0.1 %), and keeping the
  body axes keeps the interference estimate in the aircraft's axes (applying a 0.2° estimate
  moves it by |T| · 0.2° ≈ 90 nT). Without attitude, position or date, or with too little
  attitude variation, ``auto`` keeps the body axes and says so.
* ``identity`` takes the sensor axes for the body axes.
* ``FILE`` is a JSON object, fluxgate id → mount (:func:`read_mount_file`).

Whatever the mode, the mount is estimated when the data allow it, and a used mount more than
:data:`~aeromag_env.flight.mounting.WARN_ANGLE_DEG` from the estimate is warned about
(:func:`~aeromag_env.flight.mounting.mount_warning`).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from aeromag_env.errors import AeromagError
from aeromag_env.flight.data import ATTITUDE_NAMES, POSITION_NAMES, Flight, vector_names
from aeromag_env.flight.mounting import (
    Mount,
    body_field,
    mount_residual_nt,
    mount_warning,
    solve_wahba,
)
from aeromag_env.flight.quality import spike_flags

#: ``--mount auto`` applies an estimate further than this from the body axes [deg].
APPLY_ANGLE_DEG = 1.0
#: A mount file's matrix may depart from orthonormal by this much (max |R Rᵀ − I|) [-].
ORTHONORMAL_TOL = 1e-3
#: A mount file's angles and matrix, when both are given, must agree to this [deg].
ANGLES_MATRIX_TOL_DEG = 0.1
#: Mount modes other than a file.
MOUNT_MODES = ("auto", "identity")


def read_mount_file(path: str | Path) -> dict[str, Mount]:
    """The mounts of a ``--mount FILE``: a JSON object, fluxgate id → mount.

    Each mount is either ``{"rotation": [[…], […], […]]}``, the body → sensor matrix
    (``m_sensor = R m_body``, row-major, as ``report.json`` prints it), or
    ``{"roll_deg": …, "pitch_deg": …, "yaw_deg": …}``, the ZYX angles of the sensor axes in
    body axes [deg]; when both are given (a ``mount`` block of ``report.json`` or the ``mounts``
    of ``aeromag info --json`` pasted as is), they must agree to :data:`ANGLES_MATRIX_TOL_DEG`
    and the matrix is used. The object may also be wrapped as ``{"mounts": {…}}``. The matrix
    must be finite, orthonormal to :data:`ORTHONORMAL_TOL` and a rotation (det +1); it is
    replaced by the nearest exact rotation. Every problem is a one-line :class:`AeromagError`.
    """
    try:
        data = json.loads(Path(path).read_text(encoding="utf-8"))
    except OSError as exc:
        raise AeromagError(f"--mount {path}: cannot read the file ({exc.strerror})") from None
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise AeromagError(f"--mount {path}: not a JSON file ({exc})") from None
    if isinstance(data, dict) and isinstance(data.get("mounts"), dict):
        data = data["mounts"]
    if not isinstance(data, dict) or not data:
        raise AeromagError(
            f'--mount {path}: expected a JSON object such as {{"flux_a": {{"roll_deg": 0, '
            '"pitch_deg": 0, "yaw_deg": 90}}'
        )
    return {str(k): mount_from_spec(v, f"--mount {path}: {k}") for k, v in data.items()}


def mount_from_spec(spec: Any, label: str) -> Mount:
    """One mount of a mount file (see :func:`read_mount_file`); ``label`` starts the errors."""
    angles = ("roll_deg", "pitch_deg", "yaw_deg")
    if not isinstance(spec, dict) or not ("rotation" in spec or all(a in spec for a in angles)):
        raise AeromagError(f"{label}: give 'rotation' (3×3) or 'roll_deg', 'pitch_deg', 'yaw_deg'")
    from_angles = None
    if all(a in spec for a in angles):
        values = [spec[a] for a in angles]
        numbers = all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values)
        if not (numbers and all(math.isfinite(v) for v in values)):
            raise AeromagError(f"{label}: roll_deg, pitch_deg, yaw_deg must be finite numbers")
        from_angles = Mount.from_angles_deg(*values)
    if "rotation" not in spec:
        assert from_angles is not None
        return from_angles
    mount = Mount(check_rotation(spec["rotation"], label), source="file")
    if from_angles is not None and mount.angle_to_deg(from_angles) > ANGLES_MATRIX_TOL_DEG:
        raise AeromagError(
            f"{label}: the rotation and the angles disagree by "
            f"{mount.angle_to_deg(from_angles):.2f}° (give one of them)"
        )
    return mount


def check_rotation(matrix: Any, label: str) -> np.ndarray:
    """A 3×3 rotation from nested lists: finite, orthonormal, det +1 (else a one-line error);
    returned as the nearest exact rotation (SVD)."""
    try:
        r = np.array(matrix, dtype=float)
    except (TypeError, ValueError):
        raise AeromagError(f"{label}: rotation must be a 3×3 list of numbers") from None
    if r.shape != (3, 3):
        raise AeromagError(f"{label}: rotation must be 3×3, got shape {r.shape}")
    if not np.all(np.isfinite(r)):
        raise AeromagError(f"{label}: rotation has non-finite entries")
    error = float(np.max(np.abs(r @ r.T - np.eye(3))))
    if error > ORTHONORMAL_TOL:
        raise AeromagError(
            f"{label}: rotation is not orthonormal (max |R Rᵀ − I| = {error:.2g} > "
            f"{ORTHONORMAL_TOL:g})"
        )
    if np.linalg.det(r) < 0:
        raise AeromagError(
            f"{label}: rotation has det −1 (a reflection: one sensor axis flipped), not +1"
        )
    u, _, vt = np.linalg.svd(r)
    return u @ vt


@dataclass(frozen=True)
class MountChoice:
    """The mount used for one fluxgate, the estimate, and why.

    Attributes
    ----------
    fluxgate : str
    mode : str
        ``auto``, ``identity`` or ``file``.
    used : Mount
        The mount the fluxgate is taken to have (the body axes when none is applied).
    applied : bool
        Whether the compensator rotates the fluxgate by ``used`` first.
    estimate : Mount or None
        The data's own estimate (None when it could not be made).
    used_residual_nt : float
        RMS misfit of ``used`` on the estimate's samples [nT] (NaN without them).
    reason, warning : str, str or None
    """

    fluxgate: str
    mode: str
    used: Mount
    applied: bool
    estimate: Mount | None
    used_residual_nt: float
    reason: str
    warning: str | None

    @property
    def mount(self) -> Mount | None:
        """The rotation to apply (``compensate_vector(mount=…)``), None for the body axes."""
        return self.used if self.applied else None

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready: the used mount's angles and residual, the estimate, the reason."""
        used = {
            k: v for k, v in self.used.to_dict().items() if k not in ("conditioning", "samples")
        }
        used["residual_nt"] = None if math.isnan(self.used_residual_nt) else self.used_residual_nt
        estimate = None
        if self.estimate is not None:
            estimate = {
                **self.estimate.to_dict(),
                "angle_from_body_deg": Mount.identity().angle_to_deg(self.estimate),
                "angle_to_used_deg": self.used.angle_to_deg(self.estimate),
            }
        return {
            "fluxgate": self.fluxgate,
            "mode": self.mode,
            "applied": self.applied,
            **used,
            "estimate": estimate,
            "reason": self.reason,
            "warning": self.warning,
        }


def choose_mount(
    flight: Flight,
    flux: str,
    mode: str = "auto",
    given: Mount | None = None,
    mask: np.ndarray | None = None,
    relevant: bool = True,
) -> MountChoice:
    """Decide the mount of ``flux`` (module docstring), estimating it when the data allow.

    ``given`` is the file's mount (``mode="file"``); ``mask`` (n,) restricts the estimate (the
    calibration window); spike-flagged samples are left out of it. ``relevant=False`` (a method
    the mount cannot change, Tolles–Lawson) reports without applying or warning.
    """
    estimate, m, t, note = _estimate(flight, flux, mask)
    used, reason = _decide(mode, given, estimate, note)
    applied = relevant and not np.array_equal(used.rotation, np.eye(3))
    warning = None
    if not relevant:
        reason += "; not applied: the method does not depend on the fluxgate's axes"
    elif estimate is not None:
        warning = mount_warning(used, estimate, flux)
    elif mode == "auto":
        warning = f"{flux}: mount not estimated ({note}); sensor axes taken for body axes"
    residual = mount_residual_nt(used, m, t) if estimate is not None else math.nan
    return MountChoice(flux, mode, used, applied, estimate, residual, reason, warning)


def in_body_axes(flight: Flight, choice: MountChoice) -> Flight:
    """The flight with the fluxgate's readings rotated into body axes by the applied mount
    (the same object when none is applied), for tools that read the fluxgate directly."""
    if choice.mount is None:
        return flight
    body = choice.mount.to_body(flight.vector(choice.fluxgate))
    rotated = dict(zip(vector_names(choice.fluxgate), body.T, strict=True))
    return Flight({**flight.fields, **rotated}, flight.attrs)


def _decide(mode: str, given: Mount | None, estimate: Mount | None, note: str) -> tuple[Mount, str]:
    """The mount to take and why, per mode (module docstring)."""
    if mode == "file":
        assert given is not None
        return given, "from the mount file"
    if mode == "identity":
        return Mount.identity(), "--mount identity: sensor axes taken for body axes"
    if estimate is None:
        return Mount.identity(), f"not estimated ({note}); sensor axes taken for body axes"
    angle = Mount.identity().angle_to_deg(estimate)
    if angle > APPLY_ANGLE_DEG:
        return estimate, f"estimated from the data, {angle:.1f}° from the body axes"
    return Mount.identity(), (
        f"estimate {angle:.2f}° from the body axes (≤ {APPLY_ANGLE_DEG:g}°, within what the "
        "induced matrix absorbs): body axes kept"
    )


def _estimate(
    flight: Flight, flux: str, mask: np.ndarray | None
) -> tuple[Mount | None, np.ndarray, np.ndarray, str]:
    """(estimate or None, readings and model field it used, why not) for :func:`choose_mount`."""
    empty = np.empty((0, 3))
    missing = estimate_inputs_missing(flight)
    if missing:
        return None, empty, empty, f"no {missing} in the file"
    use = ~spike_flags(flight, [flux])[flux]
    if mask is not None:
        use &= mask
    m, t = flight.vector(flux)[use], body_field(flight)[use]
    try:
        return solve_wahba(m, t), m, t, ""
    except AeromagError as exc:
        return None, empty, empty, str(exc).removeprefix("cannot estimate the fluxgate mount: ")


def estimate_inputs_missing(flight: Flight) -> str:
    """What a mount estimate needs and the flight lacks (attitude, position, date), or ``""``."""
    missing = []
    if any(nm not in flight for nm in ATTITUDE_NAMES):
        missing.append("attitude")
    if any(nm not in flight for nm in POSITION_NAMES) or flight.altitude_name() is None:
        missing.append("position")
    try:
        flight.date()
    except KeyError:
        missing.append("date")
    except (ValueError, OverflowError):  # there, but unreadable or outside IGRF-14's years
        missing.append("usable date")
    return ", ".join(missing)
