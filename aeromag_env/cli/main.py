"""The ``aeromag`` command line: one entry point, one subcommand per job.

Every subcommand has ``--help``, writes its results atomically, and on bad input exits with
status 2 and a one-line message on stderr (no traceback). The parser is in
:mod:`aeromag_env.cli.parser`, the subcommands' handlers in :mod:`aeromag_env.cli.commands`.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence

from aeromag_env.cli.commands import FLIGHT_SUFFIXES, simulation_summary
from aeromag_env.cli.parser import build_parser
from aeromag_env.errors import AeromagError

__all__ = ["FLIGHT_SUFFIXES", "build_parser", "main", "simulation_summary"]


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``aeromag``.

    Parameters
    ----------
    argv : sequence of str, optional
        Arguments after the program name (default: ``sys.argv[1:]``).

    Returns
    -------
    int
        Exit status: 0, 2 on bad input (one line on stderr), 130 when interrupted.
    """
    args = build_parser().parse_args(argv)
    try:
        return int(args.func(args))
    except AeromagError as e:
        print(f"aeromag {args.command}: error: {e}", file=sys.stderr)
        return 2
    except OSError as e:
        print(
            f"aeromag {args.command}: error: {e.strerror or e}: {e.filename or ''}", file=sys.stderr
        )
        return 2
    except KeyboardInterrupt:
        print(
            f"aeromag {args.command}: interrupted; no output was left half-written", file=sys.stderr
        )
        return 130


if __name__ == "__main__":
    sys.exit(main())
