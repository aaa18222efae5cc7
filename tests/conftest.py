"""Shared fixtures."""

from __future__ import annotations

import os
from collections.abc import Iterator

import pytest

from aeromag_env.flight.data import Flight
from tests._flights import simulated


@pytest.fixture(scope="session")
def nominal_box() -> Flight:
    return simulated("nominal", 0)


@pytest.fixture(scope="session", autouse=True)
def sb3_logs_in_pytest_tmp(tmp_path_factory: pytest.TempPathFactory) -> Iterator[None]:
    """Tests that build stable-baselines3 models log into pytest's temporary folder, not into
    a new ``/tmp/SB3-<date>`` folder per model."""
    before = os.environ.get("SB3_LOGDIR")
    os.environ["SB3_LOGDIR"] = str(tmp_path_factory.mktemp("sb3"))
    yield
    if before is None:
        del os.environ["SB3_LOGDIR"]
    else:
        os.environ["SB3_LOGDIR"] = before


@pytest.fixture(scope="session")
def local_ray() -> Iterator[None]:
    """One local Ray session with 2 CPUs (the machines' cores) for the ``ray`` tests; the
    commands' ``--ray`` joins it instead of starting their own."""
    import ray  # the ray extra, installed by scripts/bootstrap: missing is a failure, not a skip

    ray.init(
        address="local",
        num_cpus=2,
        include_dashboard=False,
        log_to_driver=False,
        logging_level="ERROR",
    )  # a new Ray, never one another process started
    yield
    ray.shutdown()
