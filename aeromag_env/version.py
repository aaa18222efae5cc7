"""The package's version, in one place below every other module (the package root and the jobs
that record it in their outputs read it from here)."""

__version__ = "0.1.0"
