"""The reduced mode: ``AEROMAG_QUICK=1`` in the environment runs every long command at its quick
size, as if given ``--quick`` (docs/getting-started.md says it once; the documentation's walk,
``tests/test_docs_walk.py``, runs the pages' commands so).

What it shrinks: ``aeromag train`` and ``aeromag tune`` take their ``--quick`` sizes and do not
use a ``--timesteps`` or ``--samples`` given; ``aeromag bench`` and ``aeromag reproduce-paper``
run as with ``--quick``; ``aeromag evaluate`` flies at most the experiments' quick number of
flights per scenario; ``python -m agents.training.zoo TARGET`` writes a recipe at the quick sizes.
A command says so in one line on stderr. The sizes are :data:`agents.training.quick.QUICK`'s.
"""

from __future__ import annotations

import argparse
import os
from collections.abc import Mapping

from aeromag_env.errors import AeromagError

#: The environment variable of the reduced mode.
QUICK_VARIABLE = "AEROMAG_QUICK"


def quick_requested(environ: Mapping[str, str] | None = None) -> bool:
    """Whether the reduced mode is on: :data:`QUICK_VARIABLE` is ``1`` (unset, empty or ``0``:
    off).

    Raises
    ------
    AeromagError
        Any other value (one line: a typo should not silently run hours of training).
    """
    value = (os.environ if environ is None else environ).get(QUICK_VARIABLE, "").strip()
    if value in ("", "0"):
        return False
    if value == "1":
        return True
    raise AeromagError(
        f"{QUICK_VARIABLE} must be 1 (every command at its quick size) or 0, got {value!r}"
    )


def add_quick_option(parser: argparse.ArgumentParser, help: str) -> None:
    """A script's ``--quick`` flag (``help`` says its sizes), on by default in the reduced mode
    (:func:`quick_requested`); a value of :data:`QUICK_VARIABLE` other than 0 or 1 is the
    parser's one-line error."""
    try:
        default = quick_requested()
    except AeromagError as e:
        parser.error(str(e))
    parser.add_argument(
        "--quick", action="store_true", default=default, help=f"{help}; also {QUICK_VARIABLE}=1"
    )
