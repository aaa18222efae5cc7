"""Exceptions whose message is shown to the user as one line (the CLI prints it, exits 2), and the
one category of the package's warnings (the CLI prints each as ``aeromag: warning: …``)."""

from __future__ import annotations

import os
import sys
import types
import warnings


class AeromagError(Exception):
    """Base class: an input or option problem the user can fix; the message is one line."""


class FlightFileError(AeromagError, ValueError):
    """A flight file is unreadable, incomplete or implausible."""


class ConfigError(AeromagError, ValueError):
    """A configuration value is invalid; the message names the field and its unit."""


class PolicyFileError(AeromagError, ValueError):
    """A tuning policy file is unreadable or malformed; the message names the file."""


class HyperparameterError(AeromagError, ValueError):
    """A hyperparameter file is unreadable or invalid; the message names the file and field."""


class AeromagWarning(UserWarning):
    """Something the user should know about a run that still completes: a channel chosen for
    them, a fluxgate mount estimated or doubted, a caveat of a result. The message is one line."""


#: The package's folder: :func:`warn` attributes a warning to the first frame outside it.
_PACKAGE_DIR = os.path.dirname(os.path.abspath(__file__)) + os.sep


def warn(message: str) -> None:
    """Issue ``message`` as an :class:`AeromagWarning`, attributed to the caller's own code (the
    first frame outside ``aeromag_env``), so that Python shows where the user called in."""
    level = 2
    frame: types.FrameType | None = sys._getframe(1)
    while frame is not None and frame.f_code.co_filename.startswith(_PACKAGE_DIR):
        level, frame = level + 1, frame.f_back
    warnings.warn(message, AeromagWarning, stacklevel=level)
