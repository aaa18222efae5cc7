"""How the command line shows the jobs' warnings: each :class:`~aeromag_env.errors.AeromagWarning`
as one line ``aeromag CMD: warning: …`` on stderr, as it is issued (other warnings as Python shows
them)."""

from __future__ import annotations

import contextlib
import sys
import warnings
from collections.abc import Iterator
from typing import Any, TextIO

from aeromag_env.jobs import AeromagWarning


def warn_stderr(command: str, message: str) -> None:
    """Print one warning line of ``aeromag command`` on stderr."""
    print(f"aeromag {command}: warning: {message}", file=sys.stderr, flush=True)


@contextlib.contextmanager
def warnings_on_stderr(command: str) -> Iterator[None]:
    """Within the block, every :class:`AeromagWarning` is printed by :func:`warn_stderr`, each
    time it is issued (not once per place, as Python's default filter would)."""
    shown = warnings.showwarning

    def show(
        message: Warning | str,
        category: type[Warning],
        filename: str,
        lineno: int,
        file: TextIO | None = None,
        line: str | None = None,
    ) -> Any:
        if issubclass(category, AeromagWarning):
            warn_stderr(command, str(message))
        else:
            shown(message, category, filename, lineno, file, line)

    with warnings.catch_warnings():
        warnings.simplefilter("always", AeromagWarning)
        warnings.showwarning = show
        yield
