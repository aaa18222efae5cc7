"""Shared fixtures."""

from __future__ import annotations

import pytest

from aeromag_env.flight.data import Flight
from tests._flights import simulated


@pytest.fixture(scope="session")
def nominal_box() -> Flight:
    return simulated("nominal", 0)
