"""Shared fixtures, and the hypothesis profiles.

The default run is deterministic: every property test draws the examples that a hash of its
own source seeds (``derandomize``), nothing is replayed from a database of earlier runs, and
no timing decides a result (no deadline, no "too slow" health check: two cores shared with
other work under pytest-xdist make any time limit a matter of chance). So the README's test
command passes or fails alike on every machine, every time.

``HYPOTHESIS_PROFILE=explore`` (CI's slow step) draws fresh random examples, four times as
many (:func:`tests._helpers.examples`; 60 instead of 25 for the fault suite's examples of a
few seconds each), and keeps what fails in hypothesis's database (``.hypothesis/``) to replay
it first on the next exploring run. A failure found so is fixed and kept as an ``@example`` on
its test, where the default run tries it every time. The profile is loaded here whatever the
environment says, so hypothesis's own ``ci`` profile (which it loads when ``CI`` is set) does
not make CI's run differ from a developer's.
"""

from __future__ import annotations

import os
from collections.abc import Iterator

import pytest
from hypothesis import HealthCheck, settings

from aeromag_env.flight.data import Flight
from tests._flights import simulated
from tests._helpers import DETERMINISTIC, EXPLORE, hypothesis_profile

_UNTIMED = {"deadline": None, "suppress_health_check": [HealthCheck.too_slow], "print_blob": True}
settings.register_profile(DETERMINISTIC, derandomize=True, database=None, **_UNTIMED)
settings.register_profile(EXPLORE, derandomize=False, **_UNTIMED)
settings.load_profile(hypothesis_profile())


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
