"""The command line's own reading of option texts (``--line 1001,1002``, ``--segment T0:T1``,
``--seeds 0-4``, ``--tl-bandpass none``…) into the jobs' arguments, and the way back: the option
that spells a job's argument, for its error messages (:func:`option_for`)."""

from __future__ import annotations

import argparse
import math
from typing import Any

from aeromag_env.jobs import ArgumentError

#: A job's argument → the option that gives it, where the two are not spelled alike (the rest:
#: ``r_std_nt`` → ``--r-std-nt``).
ARGUMENT_OPTIONS = {
    "source": "FILE",
    "lines": "--line",
    "segment_s": "--segment",
    "calibration_window_s": "--calibration-window",
    "tl_bandpass_hz": "--tl-bandpass",
    "scenarios": "--scenario",
}


def option_for(parser: argparse.ArgumentParser | None, argument: str) -> str:
    """The option of ``parser`` (a subcommand's) that gives the job's ``argument``; the argument's
    own name when the subcommand has no such option."""
    name = ARGUMENT_OPTIONS.get(argument, "--" + argument.replace("_", "-"))
    if parser is None or name == "FILE":
        return name
    known = {s for action in parser._actions for s in action.option_strings}
    return name if name in known else argument


def parse_lines(text: str) -> tuple[float, ...]:
    """``--line``: ``"1001,1002"`` → ``(1001.0, 1002.0)``; a one-line error otherwise."""
    try:
        lines = tuple(float(part) for part in text.split(",") if part.strip())
    except ValueError:
        raise ArgumentError("lines", "needs line ids separated by commas", text) from None
    if not lines or not all(math.isfinite(v) for v in lines):
        raise ArgumentError("lines", "needs finite line ids separated by commas", text)
    return lines


def parse_segment(text: str) -> tuple[float, float]:
    """``--segment``: ``"T0:T1"`` [s] → ``(T0, T1)`` with ``T0 < T1``; a one-line error
    otherwise."""
    try:
        t0, t1 = (float(p) for p in text.split(":"))
    except ValueError:
        raise ArgumentError("segment_s", "needs T0:T1 in seconds", text) from None
    if not (math.isfinite(t0) and math.isfinite(t1) and t0 < t1):
        raise ArgumentError("segment_s", "needs finite T0 < T1 [s]", text)
    return t0, t1


def parse_calibration_line(text: str | None) -> str | None:
    """``--calibration-line [N]``: ``auto`` (no N), a line id as text (``1001``), or None."""
    if text is None or text == "auto":
        return text
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not math.isfinite(value):
        raise ArgumentError("calibration_line", "takes one line id (or none: auto)", text)
    return f"{value:g}"


def parse_bandpass(values: list[str]) -> tuple[float, float] | None:
    """``--tl-bandpass``: LOW HIGH [Hz], or None for the single word ``none``."""
    if len(values) == 1 and values[0].lower() == "none":
        return None
    try:
        lo, hi = (float(v) for v in values)
    except ValueError:
        raise ArgumentError(
            "tl_bandpass_hz", "takes LOW HIGH [Hz] or 'none'", " ".join(values)
        ) from None
    return lo, hi


def parse_seeds(text: str, most: int = 1000) -> tuple[int, ...]:
    """``--seeds``: ``0-4``, ``0,2,5`` or a mix (``0-2,7``) → the seeds in the given order (the
    job checks that they are distinct seeds); a range of more than ``most`` is refused here,
    before it is spelled out."""
    seeds: list[int] = []
    for part in text.split(","):
        lo, _, hi = part.strip().partition("-")
        try:
            first, last = int(lo), int(hi) if hi else int(lo)
        except ValueError:
            raise ArgumentError("seeds", "takes e.g. 0-4 or 0,2,5", text) from None
        if last < first or last - first >= most:
            raise ArgumentError(
                "seeds", f"takes ranges low-high of at most {most} seeds, low ≤ high", text
            )
        seeds += range(first, last + 1)
    return tuple(seeds)


def selection(args: argparse.Namespace) -> dict[str, Any]:
    """``--line``, ``--segment`` and ``--calibration-line`` as the jobs' ``lines``,
    ``segment_s`` and ``calibration_line``."""
    out: dict[str, Any] = {
        "lines": parse_lines(args.line) if args.line is not None else None,
        "segment_s": parse_segment(args.segment) if args.segment is not None else None,
    }
    if hasattr(args, "calibration_line"):  # info has no --calibration-line
        out["calibration_line"] = parse_calibration_line(args.calibration_line)
    return out


def triple(values: list[float] | None) -> tuple[float, float, float] | None:
    """``X Y Z`` (``nargs=3``) as a tuple (None when not given)."""
    return None if values is None else (values[0], values[1], values[2])


def window(values: list[float] | None) -> tuple[float, float] | None:
    """``--calibration-window T0 T1`` as a tuple (None when not given)."""
    return None if values is None else (values[0], values[1])


def reduced(args: argparse.Namespace) -> str | None:
    """``args`` at the reduced mode's sizes (``AEROMAG_QUICK=1``, :mod:`aeromag_env.quick`):
    ``--quick`` on, a ``--timesteps`` or ``--samples`` given dropped, ``--episodes`` capped; what
    the command says of it on stderr (None for a command with no size to reduce)."""
    from aeromag_env.jobs.evaluate import QUICK_EPISODES
    from aeromag_env.quick import QUICK_VARIABLE

    if not hasattr(args, "quick") and not hasattr(args, "episodes"):
        return None
    dropped = []
    for name in ("timesteps", "samples"):
        if getattr(args, name, None) is not None:
            dropped.append(f"--{name} {getattr(args, name)}")
            setattr(args, name, None)
    if hasattr(args, "quick"):
        args.quick = True
    if getattr(args, "episodes", 0) > QUICK_EPISODES:
        dropped.append(f"--episodes {args.episodes}")
        args.episodes = QUICK_EPISODES
    unused = f" (not {', '.join(dropped)})" if dropped else ""
    return f"{QUICK_VARIABLE}=1: the --quick sizes{unused}"
