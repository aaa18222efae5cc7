"""The ``aeromag`` command line: one entry point, one subcommand per job.

Every subcommand has ``--help``, writes its results atomically, and ends with one exit status
(:data:`EXIT_STATUS`): 0 done, 2 bad input (a one-line message on stderr, no traceback), 1 an
internal error (a bug: one line on stderr; ``AEROMAG_DEBUG=1`` shows the traceback), 130
interrupted. The parser is in :mod:`aeromag_env.cli.parser`, the subcommands' handlers in
:mod:`aeromag_env.cli.commands`.
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Sequence

from aeromag_env.cli.options import option_for, reduced
from aeromag_env.cli.parser import EXIT_STATUS, build_parser
from aeromag_env.jobs import AeromagError, ArgumentError
from aeromag_env.quick import quick_requested

__all__ = ["EXIT_STATUS", "build_parser", "main"]

#: Environment variable that lets an internal error raise with its traceback.
DEBUG_VARIABLE = "AEROMAG_DEBUG"


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``aeromag``.

    Parameters
    ----------
    argv : sequence of str, optional
        Arguments after the program name (default: ``sys.argv[1:]``).

    Returns
    -------
    int
        Exit status, one convention for every subcommand (also in ``aeromag --help``):

        * 0 — done;
        * 2 — bad input: an :class:`~aeromag_env.errors.AeromagError` (options, files), a
          rejected argument (argparse exits 2 itself) or an ``OSError`` about the user's paths;
          one line ``aeromag CMD: error: ...`` on stderr;
        * 1 — internal error: any other exception, a bug; one line ``aeromag CMD: internal
          error: TYPE: message (...)`` on stderr, or, with the environment variable
          ``AEROMAG_DEBUG=1``, the exception itself with its traceback;
        * 130 — interrupted (Ctrl-C); no output is left half-written.

    With ``AEROMAG_QUICK=1`` in the environment every command runs at its quick size
    (:mod:`aeromag_env.quick`), and says so on stderr.
    """
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        _check_paths(args)
        if quick_requested():  # the reduced mode (aeromag_env.quick)
            note = reduced(args)
            if note is not None:
                print(f"aeromag {args.command}: {note}", file=sys.stderr)
        return int(args.func(args))
    except ArgumentError as e:  # the job's argument, spelled as this command's option
        said = e.spelled(option_for(_subparser(parser, args.command), e.argument))
        print(f"aeromag {args.command}: error: {said}", file=sys.stderr)
        return 2
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
    except Exception as e:
        if os.environ.get(DEBUG_VARIABLE) == "1":
            raise
        print(
            f"aeromag {args.command}: internal error: {_one_line(e)} (a bug: please report "
            f"it with the command line; {DEBUG_VARIABLE}=1 shows the traceback)",
            file=sys.stderr,
        )
        return 1


#: The arguments that name files or folders (an empty one would silently mean ``.``).
PATH_ARGUMENTS = (
    "file",
    "input",
    "output",
    "out",
    "config",
    "replay",
    "hyperparams",
    "mount",
    "model",
)


def _check_paths(args: argparse.Namespace) -> None:
    """Refuse an empty path argument (``--out ''`` would write into the current folder)."""
    for name in PATH_ARGUMENTS:
        value = getattr(args, name, None)
        if isinstance(value, str) and not value.strip():
            flag = name if name in ("file", "input", "output") else f"--{name}"
            raise AeromagError(f"{flag} is empty; give a path")


def _subparser(parser: argparse.ArgumentParser, command: str) -> argparse.ArgumentParser | None:
    """The parser of subcommand ``command``."""
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            return action.choices.get(command)
    return None


def _one_line(exc: BaseException) -> str:
    """``TYPE: first line of the message`` (``TYPE`` alone without a message)."""
    lines = str(exc).strip().splitlines()
    return f"{type(exc).__name__}: {lines[0]}" if lines else type(exc).__name__


if __name__ == "__main__":
    sys.exit(main())
