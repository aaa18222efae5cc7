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


class ArgumentError(AeromagError, ValueError):
    """An argument of a job outside its range, named as the library spells it (``r_std_nt``);
    the command line says the same with its option's name (``--r-std-nt``).

    Parameters
    ----------
    argument : str
        The argument's name in the library (a job's keyword or its request's field).
    requirement : str
        What it must be, e.g. ``"must be in [0.001, 100000] nT (...)"``.
    got : object, optional
        The value given, appended as ``, got VALUE``.
    """

    def __init__(self, argument: str, requirement: str, got: object = None) -> None:
        self.argument = argument
        self.requirement = requirement + ("" if got is None else f", got {_shown(got)}")
        super().__init__(self.spelled(argument))

    def spelled(self, name: str) -> str:
        """The message with the argument called ``name`` (an option of the command line)."""
        return f"{name} {self.requirement}"


def _shown(value: object) -> str:
    """A value as a message shows it: numbers in ``g`` format, text quoted."""
    if isinstance(value, float):
        return f"{value:g}"
    if isinstance(value, str):
        return repr(value)
    if isinstance(value, tuple | list):
        return " ".join(_shown(v) for v in value)
    return str(value)


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
