"""The ``aeromag`` command line and the speed benchmarks; the only layer that imports ``agents``."""

from aeromag_env.cli.main import main

__all__ = ["main"]
