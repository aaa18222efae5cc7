"""The fault suite's other classes: path hazards, extreme and malformed option values, hostile
hyperparameter, policy, mount and configuration files, and each command on clean input."""

from __future__ import annotations

import io
import json
from collections.abc import Iterator

import numpy as np

from tests._helpers import SHIPPED
from tests.faults.cases import (
    BAD,
    FLIGHT_RUNNERS,
    FORMATS,
    OK,
    RUNNERS,
    Case,
    _case,
    _input,
)

#: The values every numeric option gets.
VALUES = ("nan", "inf", "-inf", "-1", "0", "1e300", "1e-300", "abc", "")
#: The first step of each heavy command's work: reaching it means a hazard was not refused first.
WORK = {
    "demo": "aeromag_env.jobs.demo.simulate_flight",
    "reproduce-paper": "aeromag_env.compensation.paper.simulate_flight",
    "bench": "aeromag_env.jobs.bench.bench_simulate",
    "train": "agents.training.ppo.make_training_env",
}

# ---------------------------------------------------------------------------------------------
# The cases, class by class


def _output_hazards(runner: str) -> list[tuple[str, tuple[str, ...], str, tuple[str, ...]]]:
    """(name, files, OUT, read-only folders) of ``--out`` hazards, all to be refused."""
    file_out = RUNNERS[runner].outputs is None
    o = "o.h5" if file_out else "o"
    found = [
        ("out_under_a_file", ("file:f",), f"@/f/{o}", ()),
        ("out_read_only", ("dir:ro",), f"@/ro/{o}", ("ro",)),
        ("out_empty", (), "", ()),
    ]
    if not file_out:
        return [*found, ("out_a_file", ("file:o",), "@/o", ())]
    found += [("out_a_folder", ("dir:o.h5",), "@/o.h5", ()), ("out_bad_suffix", (), "@/o.txt", ())]
    if RUNNERS[runner].kind:  # an input to overwrite: the output is it, or a link to it
        found += [
            ("out_is_the_input", (), "@/in.h5", ()),
            ("out_links_to_input", ("link:o.h5>in.h5",), "@/o.h5", ()),
            ("out_hard_links_input", ("hard:o.h5>in.h5",), "@/o.h5", ()),
        ]
    return found


def path_cases() -> Iterator[Case]:
    """Inputs missing, a folder, a (dangling) link, /dev/null, oddly named; outputs under a
    file, read-only, empty, a file for a folder and the reverse, another suffix, an input or a
    link to one; an input named like an output; old outputs replaced."""
    inputs = {
        "input_missing": ((), "@/nope.h5", "refused"),
        "input_dev_null": ((), "/dev/null", "refused"),
        "input_a_folder": (("dir:in.h5",), "@/in.h5", "refused"),
        "input_dangling_link": (("link:in.h5>gone.h5",), "@/in.h5", "refused"),
        "input_a_link": (("in:real.h5", "link:in.h5>real.h5"), "@/in.h5", OK),
        "input_odd_name": (("in:ä b;c'.h5",), "@/ä b;c'.h5", OK),
    }
    for name, (ops, path, expect) in inputs.items():
        for runner in FLIGHT_RUNNERS:
            yield _case("paths", name, runner, expect, ops, {"IN": path})
    for runner, r in RUNNERS.items():
        if runner in ("info", "tl", "kf"):  # no output; compensate is lsq's
            continue
        ins = _input(runner)
        for name, ops, out, frozen in _output_hazards(runner):
            yield _case("paths", name, runner, "refused", (*ins, *ops), {"OUT": out}, (), frozen)
        named = (r.outputs or ())[: 2 if runner == "discover" else None] if r.kind else ()
        for n in named:  # the input named like an output, or an output a link to the input
            swap = {"IN": ("ppo:" if r.kind == "policy" else "") + f"@/out/{n}"}
            yield _case(
                "paths", f"input_named_{n}", runner, "refused", (f"{r.kind}:out/{n}",), swap
            )
            for link in ("link", "hard") if ins else ():
                ops = (*ins, f"{link}:out/{n}>in.h5")
                yield _case("paths", f"{n}_{link}_links_to_input", runner, "refused", ops)
        if runner not in WORK:
            old = tuple(f"file:{p}" for p in _case("", "", runner, "").outputs)
            yield _case("paths", "old_outputs_replaced", runner, OK, (*ins, *old))


#: Numeric options (``{}``: the value): the values of :data:`VALUES` not refused and what they
#: get (None: a valid value not run, the work of a heavy command).
OPTIONS = (
    ("simulate", "--seed={}", {"0": OK}),
    ("simulate", "--duration-s={}", {}),
    ("tl", "--tl-trim={}", {"0": OK}),
    ("tl", "--tl-ridge={}", {"0": OK, "1e-300": OK, "1e300": "any"}),
    ("tl", "--tl-bandpass {} 0.9", {"0": OK, "1e-300": "refused"}),  # cannot be designed
    ("tl", "--tl-bandpass 0.1 {}", {"1e300": BAD}),
    ("kf", "--r-std-nt={}", {"1e-300": "any", "1e300": BAD}),
    ("lsq", "--calibration-window 10 {}", {"inf": "any", "1e300": "any"}),
    ("lsq", "--segment=0:{}", {"1e300": "any"}),
    ("lsq", "--line={}", {}),
    ("lsq", "--calibration-line={}", {}),
    ("info", "--segment=0:{}", {"1e300": "any"}),
    ("info", "--line={}", {}),
    ("discover", "--calibration-window 0 {}", {"inf": "any", "1e300": "any"}),
    ("evaluate", "--episodes={}", {}),
    ("evaluate", "--seed-start={}", {}),
    ("train", "--timesteps={}", {}),
    ("train", "--seed={}", {"0": None}),
    ("demo", "--seed={}", {"0": None}),
    ("reproduce-paper", "--seed={}", {"0": None}),
)
#: Other option values and what they get.
WORDS = (
    ("lsq", "--flux flux_b", "refused"),
    ("lsq", "--flux ''", "refused"),
    ("tl", "--scalar mag_9_uc", "refused"),
    ("lsq", "--mount sideways", "refused"),
    ("lsq", "--method bogus", "refused"),
    ("tl", "--tl-trim 100000", "refused"),
    ("tl", "--tl-bandpass 0.1 0.2 0.3", "refused"),
    ("tl", "--tl-bandpass none", OK),
    ("lsq", "--segment 30:90", OK),
    ("lsq", "--line 1", OK),
    ("lsq", "--calibration-line", "any"),
    ("evaluate", "--scenario bogus", "refused"),
    ("evaluate", "--scenario ''", "refused"),
    ("evaluate", "--scenario nonstationary_dense", "refused"),
    ("evaluate", "--episodes 1", OK),
    ("evaluate", "--policies nope", "refused"),
    ("evaluate", "--policies ,", "refused"),
    ("simulate", "--preset bogus", "refused"),
    ("simulate", "--pattern spiral", "refused"),
    ("train", "--scenario bogus", "refused"),
)


def value_cases() -> Iterator[Case]:
    """Every numeric option with each of :data:`VALUES`; the other values of :data:`WORDS`."""
    for runner, option, valid in OPTIONS:
        for value in VALUES:
            expect = valid.get(value, "refused")
            if expect is not None:
                extra = tuple(t.format(value) for t in option.split())
                name = option.replace(" ", "_").format(repr(value))
                yield _case("option values", name, runner, expect, _input(runner), extra=extra)
    for runner, option, expect in WORDS:
        extra = tuple("" if t == "''" else t for t in option.split())
        yield _case("option values", option, runner, expect, _input(runner), extra=extra)


def _policy_with_nan() -> bytes:
    """The shipped policy with one NaN weight."""
    with np.load(SHIPPED["policy"], allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files}
    arrays["w0"] = arrays["w0"].copy()
    arrays["w0"].flat[3] = np.nan
    buffer = io.BytesIO()
    np.savez(buffer, **arrays)
    return buffer.getvalue()


def hostile_cases() -> Iterator[Case]:
    """Hyperparameter, policy, mount and configuration files: empty, random, truncated, text,
    JSON of the wrong kind or with NaN, a value out of range, a folder, missing."""
    hp = json.loads(SHIPPED["hyperparams"].read_text(encoding="utf-8"))
    hp["scenarios"]["nonstationary"]["gamma"] = 2.0
    good = {
        "hyperparams": SHIPPED["hyperparams"].read_bytes(),
        "policy": SHIPPED["policy"].read_bytes(),
        "config": b'{"preset": "custom"}',
        "mount": b'{"flux_a": {"roll_deg": 0, "pitch_deg": 0, "yaw_deg": 90}}',
    }
    wrong = {
        "hyperparams": json.dumps(hp).encode(),
        "policy": _policy_with_nan(),
        "config": b'{"trajectory": {"duration_s": -5}}',
        "mount": b'{"flux_a": {"rotation": [[2, 0, 0], [0, 1, 0], [0, 0, 1]]}}',
    }
    noise = np.random.default_rng(21).bytes(2048)
    for target, runner in (
        ("hyperparams", "train"),
        ("policy", "evaluate"),
        ("mount", "lsq"),
        ("config", "simulate"),
    ):
        name = f"bad.{'npz' if target == 'policy' else 'json'}"
        if target in ("hyperparams", "policy"):  # the runner's input
            swap, extra = {"IN": ("ppo:@/" if target == "policy" else "@/") + name}, ()
        else:
            swap, extra = {}, (f"--{target}", f"@/{name}")
        contents = {
            "empty": b"",
            "random_bytes": noise,
            "text": b"hello\n",
            "truncated": good[target][: len(good[target]) // 2],
            "json_list": b"[1, 2]",
            "json_nan": b'{"flux_a": NaN, "preset": NaN}',
            "out_of_range": wrong[target],
        }
        for fault, data in contents.items():
            ops = (*_input(runner), f"data:{name}")
            yield _case(
                "hostile files",
                f"{target}_{fault}",
                runner,
                "refused",
                ops,
                swap,
                extra,
                make=lambda data=data: data,
            )
        for fault, ops in (("a_folder", (f"dir:{name}",)), ("missing", ())):
            yield _case(
                "hostile files",
                f"{target}_{fault}",
                runner,
                "refused",
                (*_input(runner), *ops),
                swap,
                extra,
            )


def clean_cases() -> Iterator[Case]:
    """Each command on the clean flight in each format; simulate, evaluate and train."""
    for runner in ("info", "tl", "lsq", "kf", "convert", "replay", "discover"):
        for fmt in ("h5",) if runner == "discover" else FORMATS:
            yield _case(
                "clean",
                f"clean/{fmt}",
                runner,
                OK,
                _input(runner, f"in.{fmt}"),
                {"IN": f"@/in.{fmt}"},
            )
    for runner in ("simulate", "evaluate", "train"):
        yield _case("clean", "clean", runner, OK)
