"""Exceptions whose message is shown to the user as one line (the CLI prints it, exits 2)."""

from __future__ import annotations


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
