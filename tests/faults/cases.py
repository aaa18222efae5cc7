"""The fault suite's commands and cases, its flight files (written here, not by the package) and
the flight-fault classes: file, missing, duplicated, mistyped, mis-unit and NaN/inf."""

from __future__ import annotations

import json
import os
import shutil
import tempfile
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from functools import cache, partial
from pathlib import Path
from typing import NamedTuple

import numpy as np

from tests._helpers import SHIPPED

FORMATS = ("h5", "csv", "xyz", "mat")
ATTITUDE = ("ins_roll", "ins_pitch", "ins_yaw")
FLUX = ("flux_a_x", "flux_a_y", "flux_a_z")
POSITION = ("tt", "lat", "lon", "alt", "date", *ATTITUDE)
#: The fields the commands need (``date``: the attribute, or the fields ``year`` and ``doy``).
CHANNELS = (*POSITION, *FLUX, "mag_1_uc")
OK, BAD = "warned|clean", "refused|warned"

# ---------------------------------------------------------------------------------------------
# Commands and cases


class Runner(NamedTuple):
    """A command on one input: ``argv`` with ``IN`` and ``OUT`` standing for the input and the
    output; their defaults; the output set in the folder OUT as its help gives it (None: OUT is
    the file written); the fields the command needs; what IN is (``in``: a flight file,
    ``in480``: a 480-s one, ``policy``, ``hyperparams``, or nothing)."""

    argv: tuple[str, ...]
    input: str
    output: str
    outputs: tuple[str, ...] | None
    needs: frozenset[str]
    kind: str


def _compensate(method: str, needs: tuple[str, ...]) -> Runner:
    argv = ("compensate", "IN", "--method", method, "--out", "OUT")
    outputs = ("compensated.h5", "report.json", "compensation.png")
    return Runner(argv, "@/in.h5", "@/out", outputs, frozenset(needs), "in")


RUNNERS = {
    "info": Runner(("info", "IN"), "@/in.h5", "", (), frozenset({"tt"}), "in"),
    "tl": _compensate("tl", ("tt", *FLUX, "mag_1_uc")),
    "lsq": _compensate("lsq", POSITION + FLUX),
    "kf": _compensate("kf", POSITION + FLUX),
    "discover": Runner(
        ("discover", "IN", "--out", "OUT", "--quiet"),
        "@/in.h5",
        "@/out",
        ("report.json", "report.md", "model_config.json", "residual.png", "diagnostics.png"),
        frozenset(POSITION + FLUX),
        "in480",
    ),
    "convert": Runner(
        ("convert", "IN", "OUT"), "@/in.h5", "@/out/conv.h5", None, frozenset({"tt"}), "in"
    ),
    "replay": Runner(
        ("simulate", "--replay", "IN", "--out", "OUT", "--quiet"),
        "@/in.h5",
        "@/out/sim.h5",
        None,
        frozenset(POSITION),
        "in",
    ),
    "simulate": Runner(
        ("simulate", "--duration-s", "60", "--out", "OUT", "--quiet"),
        "",
        "@/out/sim.h5",
        None,
        frozenset(),
        "",
    ),
    "evaluate": Runner(
        ("evaluate", "--policies", "IN", "--episodes", "2", "--out", "OUT", "--quiet"),
        "constant",
        "@/out",
        ("results.json", "evaluation.png"),
        frozenset(),
        "policy",
    ),
    "train": Runner(
        (
            "train",
            "--quick",
            "--timesteps",
            "256",
            "--hyperparams",
            "IN",
            "--out",
            "OUT",
            "--quiet",
        ),
        str(SHIPPED["hyperparams"]),
        "@/out",
        ("policy.npz", "training.json"),
        frozenset(),
        "hyperparams",
    ),
    "demo": Runner(("demo", "--out", "OUT"), "", "@/out", (), frozenset(), ""),
    "bench": Runner(("bench", "--quick", "--out", "OUT"), "", "@/out", (), frozenset(), ""),
    "reproduce-paper": Runner(
        ("reproduce-paper", "--quick", "--out", "OUT"), "", "@/out", (), frozenset(), ""
    ),
}
FLIGHT_RUNNERS = ("info", "tl", "lsq", "convert", "replay")


@dataclass(frozen=True)
class Case:
    """One fault through one command and the outcomes allowed (``"refused|warned"``…, ``"any"``).

    ``@/`` in ``argv`` starts a path in the case's folder; ``setup`` writes the files there;
    ``outputs`` (relative to it) is the output set; ``frozen``, folders made read-only for the
    run; ``about``, a pattern that a warning must match to count as one about the fault.
    """

    fault_class: str
    name: str
    argv: tuple[str, ...]
    setup: Callable[[Path], None]
    expect: str
    outputs: tuple[str, ...] = ()
    frozen: tuple[str, ...] = ()
    about: str = ""

    @property
    def id(self) -> str:
        return f"{self.fault_class}/{self.name}"


def _case(
    cls: str,
    name: str,
    runner: str,
    expect: str,
    ops: tuple[str, ...] = (),
    swap: dict[str, str] | None = None,
    extra: tuple[str, ...] = (),
    frozen: tuple[str, ...] = (),
    about: str = "",
    **files: object,
) -> Case:
    """``runner`` with its IN, OUT (and any other argument) replaced by ``swap`` and ``extra``
    appended; the files made by :func:`setup` (``ops`` and the keywords ``fault``, ``make``)."""
    r = RUNNERS[runner]
    swap = {"IN": r.input, "OUT": r.output, **(swap or {})}
    out = swap["OUT"].removeprefix("@/")
    outputs = (out,) if r.outputs is None else tuple(str(Path(out, n)) for n in r.outputs)
    argv = (*(swap.get(a, a) for a in r.argv), *extra)
    setup_files = partial(setup, ops=ops, **files)
    return Case(cls, f"{name}/{runner}", argv, setup_files, expect, outputs, frozen, about)


def _input(runner: str, name: str = "in.h5") -> tuple[str, ...]:
    """The setup of ``runner``'s clean input flight file, if it reads one."""
    kind = RUNNERS[runner].kind
    return (f"{kind}:{name}",) if kind.startswith("in") else ()


# ---------------------------------------------------------------------------------------------
# Files


@cache
def base(duration_s: float = 120.0) -> tuple[dict[str, np.ndarray], dict[str, object]]:
    """Fields and attributes of the clean nominal flight (seed 0, ``duration_s`` [s])."""
    from aeromag_env.simulation.config import preset, with_overrides
    from aeromag_env.simulation.simulate import simulate_flight

    cfg = with_overrides(preset("nominal"), {"trajectory.duration_s": duration_s})
    flight = simulate_flight(cfg, 0)
    return flight.fields, flight.attrs


def write(path: Path, columns: list[tuple[str, np.ndarray]], attrs: dict[str, object]) -> None:
    """Columns of any type, shape and name (twice too) in the format of ``path``'s suffix (HDF5
    for another suffix), written directly: the readers under test get files they did not write."""
    fmt = path.suffix[1:] if path.suffix[1:] in FORMATS else "h5"
    if fmt == "h5":
        import h5py

        with h5py.File(path, "w") as f:
            for name, values in columns:
                f[name] = values.astype("S") if values.dtype.kind == "U" else values
            f.attrs.update({k: str(v) for k, v in attrs.items()})
    elif fmt == "mat":
        import scipy.io

        columns = [(k, v.reshape(-1, 1) if v.ndim == 1 else v) for k, v in columns]
        scipy.io.savemat(path, {**dict(columns), "aeromag_attrs": json.dumps(attrs)})
    else:
        sep, mark, names = (",", "#@ ", "") if fmt == "csv" else (" ", "/ @ ", "/ ")
        head = [mark + json.dumps(attrs), names + sep.join(dict(columns))]
        rows = (sep.join(_cell(v[i]) for _, v in columns) for i in range(len(columns[0][1])))
        path.write_text("\n".join([*head, *rows]) + "\n", encoding="utf-8")


def _cell(value: object) -> str:
    return repr(float(value)) if isinstance(value, np.floating) else str(value)


#: A fault edits the fields and attributes in place, or returns the columns to write instead.
Fault = Callable[[dict, dict], "list[tuple[str, np.ndarray]] | None"]


@cache
def clean_bytes(fmt: str, duration_s: float = 120.0) -> bytes:
    """The clean flight's file in format ``fmt``."""
    fields, attrs = base(duration_s)
    with tempfile.TemporaryDirectory() as tmp:
        write(Path(tmp, f"in.{fmt}"), list(fields.items()), attrs)
        return Path(tmp, f"in.{fmt}").read_bytes()


def setup(
    d: Path, ops: tuple[str, ...], fault: Fault | None = None, make: Callable[[], bytes] = bytes
) -> None:
    """A case's files in ``d``: ``in:NAME`` the clean flight with ``fault`` (``in480:``, 480 s
    long), ``data:NAME`` the bytes ``make()``, ``dir:``, ``file:`` (a few bytes),
    ``link:NAME>TARGET``, ``hard:NAME>TARGET``, ``policy:`` and ``hyperparams:`` (copies of
    the shipped files)."""
    for op in ops:
        kind, _, arg = op.partition(":")
        name, _, target = arg.partition(">")
        path, duration = d / name, 480.0 if kind == "in480" else 120.0
        path.parent.mkdir(parents=True, exist_ok=True)
        if kind.startswith("in") and fault is None:
            suffix = path.suffix[1:]
            path.write_bytes(clean_bytes(suffix if suffix in FORMATS else "h5", duration))
        elif kind.startswith("in"):
            fields, attrs = base(duration)
            fields, attrs = {k: v.copy() for k, v in fields.items()}, dict(attrs)
            write(path, fault(fields, attrs) or list(fields.items()), attrs)
        elif kind in ("data", "file"):
            path.write_bytes(make() if kind == "data" else b"old\n")
        elif kind == "dir":
            path.mkdir()
        elif kind == "link":
            path.symlink_to(d / target)
        elif kind == "hard":
            os.link(d / target, path)
        else:
            shutil.copy(SHIPPED[kind], path)


def _drop(f: dict, a: dict, name: str) -> None:
    for nm in ("year", "doy") if name == "date" else (name,):
        del f[nm]
    if name == "date":
        del a["date"]


def _change(fn: Callable[[np.ndarray], np.ndarray], *names: str) -> Fault:
    """``fn`` applied to the fields ``names``; a changed ``year`` loses the ``date`` attribute,
    which would stand in for it."""

    def fault(f: dict, a: dict) -> None:
        f.update({nm: fn(f[nm]) for nm in names})
        if "year" in names:
            del a["date"]

    return fault


def _set(lo: int, hi: int | None, value: float, x: np.ndarray) -> np.ndarray:
    """``x`` with ``x[lo:hi]`` set to a non-finite ``value``, or with a finite one added."""
    x = x.copy()
    x[lo:hi] = x[lo:hi] + value if np.isfinite(value) else value
    return x


def _retype(kind: str, x: np.ndarray) -> np.ndarray:
    if kind == "string":
        return np.array([f"v{v:.3f}" for v in x])
    return {
        "complex": lambda: x + 1j,
        "bool": lambda: x > np.median(x),
        "2d": lambda: np.column_stack([x, x]),
        "short": lambda: x[:-7],
    }[kind]()


def _truncated(fmt: str, fraction: float) -> bytes:
    data = clean_bytes(fmt)
    cut = int(len(data) * fraction)
    while fmt in ("csv", "xyz") and b"\n" in data[cut - 2 : cut + 1]:
        cut -= 3  # mid-row: a cut at a row's end leaves a valid, shorter file
    return data[:cut]


# ---------------------------------------------------------------------------------------------
# The cases, class by class


def _grid(
    cls: str, faults: dict[str, tuple], runners: tuple[str, ...], formats: tuple[str, ...] = ("h5",)
) -> Iterator[Case]:
    """Fault × format × runner. ``faults`` maps a name to (fault, fields, outcome expected when
    the runner needs one of the fields, outcome otherwise[, what a warning must name: by default
    one of the fields])."""
    named = {"date": "date|year|doy", **dict.fromkeys(FLUX, "flux_a")}
    for name, (fault, fields, needed, other, *about) in faults.items():
        about = about or [r"\b(" + "|".join(named.get(f, f) for f in fields) + ")"]
        for fmt, runner in ((f, r) for f in formats for r in runners):
            expect = needed if RUNNERS[runner].needs.intersection(fields) else other
            expect = expect.get(runner, expect["*"]) if isinstance(expect, dict) else expect
            ops, swap = _input(runner, f"in.{fmt}"), {"IN": f"@/in.{fmt}"}
            yield _case(
                cls, f"{name}/{fmt}", runner, expect, ops, swap, about=about[0], fault=fault
            )


def file_cases() -> Iterator[Case]:
    """Truncated, random, empty, blank, zero, PNG, JSON, non-UTF-8 text or another format's
    bytes, in each format, through each reader."""
    noise = np.random.default_rng(20).bytes(4096)
    for fmt in FORMATS:
        faults: dict[str, Callable[[], bytes]] = {
            **{f"truncated_{f:g}": partial(_truncated, fmt, f) for f in (0.05, 0.5, 0.97)},
            "random_bytes": lambda: noise,
            "empty": bytes,
            "blank_lines": lambda: b"\n \n",
            "png": lambda: b"\x89PNG\r\n\x1a\n" + noise[:512],
            "zeros": lambda: bytes(2048),
            "json": lambda: b'{"tt": [0, 0.1, 0.2], "lat": [45, 45, 45]}\n',
            **{f"{o}_content": partial(clean_bytes, o) for o in FORMATS if o != fmt},
        }
        if fmt == "csv":
            faults["latin1_name"] = lambda: clean_bytes("csv").replace(b"diurnal", b"diurn\xe9")
        for fault, make in faults.items():
            text_cut = fault.startswith("trunc") and fmt in ("csv", "xyz")
            expect = BAD if text_cut or fault == "latin1_name" else "refused"
            expect, about = ("warned", "suffix") if fault.endswith("_content") else (expect, "")
            for runner in FLIGHT_RUNNERS:
                yield _case(
                    "file",
                    f"{fault}/{fmt}",
                    runner,
                    expect,
                    (f"data:in.{fmt}",),
                    {"IN": f"@/in.{fmt}"},
                    about=about,
                    make=make,
                )


def field_cases() -> Iterator[Case]:
    """Each needed field missing; duplicated (an alias beside its name, two aliases of one
    name, a column twice); mistyped (text, complex, bool, 2-D, short)."""
    missing = {nm: (partial(_drop, name=nm), (nm,), "refused", OK) for nm in CHANNELS}
    yield from _grid("missing", missing, FLIGHT_RUNNERS, FORMATS)
    some = {k: missing[k] for k in ("lat", "ins_yaw", "flux_a_z")}
    yield from _grid("missing", some, ("discover",))
    twins = {
        "TIME": "tt",
        "LAT": "lat",
        "ins_azim": "ins_yaw",
        "UNCOMPMAG1": "mag_1_uc",
        "FLUXA_X": "flux_a_x",
    }
    beside = {
        f"{a}+{n}": (
            lambda f, _, a=a, n=n: [*f.items(), (a, f[n] * 1.01 + 1.0)],
            (n,),
            "warned",
            "warned",
        )
        for a, n in twins.items()
    }
    yield from _grid("duplicated", beside, FLIGHT_RUNNERS, ("h5", "csv", "mat"))
    yield from _grid("duplicated", _text_twins(), ("info", "lsq", "convert"), ("csv", "xyz"))
    for fmt in FORMATS:
        kinds = ("string", "complex", "bool", *(("2d", "short") if fmt in ("h5", "mat") else ()))
        faults = {
            f"{nm}_{kind}": (
                _change(partial(_retype, kind), nm),
                CHANNELS if kind == "short" else (nm,),
                "refused",
                BAD,
            )
            for kind in kinds
            for nm in ("tt", "lat", "ins_roll", "flux_a_x", "mag_1_uc")
        }
        runners = FLIGHT_RUNNERS if fmt == "h5" else ("info", "lsq")
        yield from _grid("mistyped", faults, runners, (fmt,))


def _text_twins() -> dict[str, tuple]:
    """Two aliases of ``ins_roll`` (ROLL, roll) without it; ``lat`` twice in a text header."""

    def roll(f: dict, _: dict) -> list:
        rest = [(k, v) for k, v in f.items() if k != "ins_roll"]
        return [*rest, ("ROLL", f["ins_roll"]), ("roll", f["ins_roll"] + 1.0)]

    def twice(f: dict, _: dict) -> list:
        return [*f.items(), ("lat", f["lat"] + 0.5)]

    return {
        "ROLL+roll": (roll, ("ins_roll",), "warned", "warned"),
        "lat_twice": (twice, ("lat",), BAD, BAD),
    }


def unit_cases() -> Iterator[Case]:
    """Attitude and latitude in radians, time in ms, altitude in feet (beside a utm_z in metres,
    or alone: undetectable), magnetometers in µT or T, a two-digit year."""

    def feet(f: dict, _: dict) -> list:
        return [*{**f, "alt": f["alt"] * 3.28084, "utm_z": f["alt"]}.items()]

    faults = {
        "attitude_radians": (_change(np.deg2rad, *ATTITUDE), ATTITUDE, BAD, BAD),
        "lat_lon_radians": (_change(np.deg2rad, "lat", "lon"), ("lat",), BAD, OK, "lat|lon"),
        "time_ms": (_change(lambda t: t * 1e3, "tt"), (*FLUX, "lat"), BAD, OK, r"\btt|time|rate"),
        "alt_feet_beside_utm_z": (feet, ("alt",), BAD, OK),
        "alt_feet_alone": (_change(lambda z: z * 3.28084, "alt"), ("alt",), OK, OK),
        "flux_microtesla": (_change(lambda b: b / 1e3, *FLUX), FLUX, "refused", BAD),
        "flux_tesla": (_change(lambda b: b * 1e-9, *FLUX), FLUX, "refused", BAD),
        "scalar_microtesla": (
            _change(lambda b: b / 1e3, "mag_1_uc"),
            ("mag_1_uc",),
            "refused",
            BAD,
        ),
        "year_two_digits": (_change(lambda y: y - 2000.0, "year"), ("date",), "refused", OK),
    }
    runners = ("info", "tl", "lsq", "kf", "convert", "replay")
    yield from _grid("mis-unit", faults, runners)
    again = {k: faults[k] for k in ("attitude_radians", "time_ms")}
    yield from _grid("mis-unit", again, runners, ("csv",))


def nonfinite_cases() -> Iterator[Case]:
    """NaN and ±inf bursts, a channel all NaN, a 1e6 nT spike, in each channel (``tt``: always
    refused; an all-NaN channel: refused when needed)."""
    kinds = {
        "nan_burst": ((300, 350, np.nan), (*FLIGHT_RUNNERS, "kf")),
        "inf_burst": ((600, 610, np.inf), ("info", "lsq", "kf", "convert")),
        "neg_inf": ((900, 901, -np.inf), ("tl", "lsq")),
        "all_nan": ((0, None, np.nan), ("info", "tl", "lsq", "replay")),
    }
    for kind, (args, runners) in kinds.items():
        needed = "refused" if kind == "all_nan" else "warned"
        flown = {"replay": "refused", "*": needed}  # a replay cannot fly through a hole
        faults = {
            f"{nm}_{kind}": (
                _change(partial(_set, *args), nm),
                (nm,),
                flown if nm in POSITION else needed,
                "warned",
            )
            for nm in ("tt", "lat", "lon", "alt", *CHANNELS[5:])
        }
        faults[f"tt_{kind}"] = (*faults[f"tt_{kind}"][:2], "refused", "refused")
        year = _change(partial(_set, *args), "year")  # the date's source once the attribute goes
        faults[f"year_{kind}"] = (year, ("date",), needed, BAD if kind == "all_nan" else "warned")
        yield from _grid("NaN/inf", faults, runners)
    for kind, (lo, hi, value), runners, formats in (
        ("spike_1e6", (700, 701, 1e6), ("info", "tl", "lsq", "kf"), ("h5",)),
        ("nan_burst", (300, 350, np.nan), ("info", "lsq"), ("csv", "xyz", "mat")),
    ):
        names = ("flux_a_y", "mag_1_uc") if kind == "spike_1e6" else ("ins_pitch", "flux_a_x")
        faults = {
            f"{nm}_{kind}": (_change(partial(_set, lo, hi, value), nm), (nm,), "warned", "warned")
            for nm in names
        }
        yield from _grid("NaN/inf", faults, runners, formats)
