"""Fault injection: hostile policy files (``ppo:PATH``) get one clear line, at load time.

Every case is generated here from the shipped policy
(``agents/policies/trained/ppo_nonstationary.npz``)
by class: bytes that are no archive, broken archives, archives without the arrays, wrong
shapes, non-finite or out-of-range values, wrong dtypes and bad metadata. Each must raise
:class:`~aeromag_env.errors.PolicyFileError` whose message is one line naming the file and the
problem; nothing in the file is ever unpickled.
"""

from __future__ import annotations

import io
import json
import pickle
import zipfile
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from aeromag_env.cli.main import main
from aeromag_env.errors import AeromagError, PolicyFileError
from agents.policies import DEFAULT_PPO, make_policy, policy_env_kwargs
from agents.policies.numpy_policy import NumpyPPOPolicy
from tests._helpers import assert_one_line_error, examples

Arrays = dict[str, np.ndarray]


def _shipped() -> Arrays:
    with np.load(DEFAULT_PPO, allow_pickle=False) as data:
        return {k: data[k].copy() for k in data.files}


def _meta(arrays: Arrays) -> dict:
    return json.loads(str(arrays["meta"]))


def _with_meta(arrays: Arrays, change: Callable[[dict], object]) -> Arrays:
    meta = _meta(arrays)
    change(meta)
    return {**arrays, "meta": np.array(json.dumps(meta))}


def _set(key: str, value: object) -> Callable[[Arrays], Arrays]:
    return lambda a: {**a, key: np.asarray(value)}


def _poke(key: str, value: float, index: int = 0) -> Callable[[Arrays], Arrays]:
    def mutate(a: Arrays) -> Arrays:
        arr = a[key].astype(np.float64).copy()
        arr.reshape(-1)[index] = value
        return {**a, key: arr}

    return mutate


def _drop(key: str) -> Callable[[Arrays], Arrays]:
    return lambda a: {k: v for k, v in a.items() if k != key}


#: Array-level faults: (case, mutation of the shipped arrays, the problem the message names).
ARRAY_FAULTS: list[tuple[str, Callable[[Arrays], Arrays], str]] = [
    *[
        (f"missing_{k}", _drop(k), f"missing.*{k}")
        for k in ("obs_mean", "obs_var", "obs_clip", "obs_eps", "w_out", "b_out", "meta")
    ],
    ("missing_w1", _drop("w1"), "b1 without w1|hidden layer"),
    ("missing_b0", _drop("b0"), "missing.*b0"),
    (
        "layer_gap",
        lambda a: {**_drop("w1")(_drop("b1")(a)), "w2": a["w1"], "b2": a["b1"]},
        "hidden layer",
    ),
    ("unexpected_array", lambda a: {**a, "w_extra": a["w0"]}, "unexpected.*w_extra"),
    ("obs_mean_2d", lambda a: {**a, "obs_mean": a["obs_mean"].reshape(2, 5)}, "obs_mean.*shape"),
    ("obs_var_short", lambda a: {**a, "obs_var": a["obs_var"][:-1]}, "obs_var.*shape"),
    ("obs_clip_vector", _set("obs_clip", [10.0, 10.0]), "obs_clip.*scalar"),
    ("obs_eps_vector", _set("obs_eps", [1e-8]), "obs_eps.*scalar"),
    ("w0_transposed", lambda a: {**a, "w0": a["w0"].T.copy()}, "w0.*shape"),
    ("w0_3d", lambda a: {**a, "w0": a["w0"][None]}, "w0.*shape"),
    ("b0_short", lambda a: {**a, "b0": a["b0"][:-1]}, "b0.*shape"),
    ("w1_narrow", lambda a: {**a, "w1": a["w1"][:, :-1]}, "w1.*shape"),
    ("w_out_narrow", lambda a: {**a, "w_out": a["w_out"][:, :-1]}, "w_out.*shape"),
    ("b_out_short", lambda a: {**a, "b_out": a["b_out"][:-1]}, "b_out.*shape"),
    (
        "two_actions_for_three",
        lambda a: {**a, "w_out": a["w_out"][:2], "b_out": a["b_out"][:2]},
        "2 actions.*3",
    ),
    (
        "observations_for_another_layout",
        lambda a: _with_meta(a, lambda m: m.update(env_kwargs={"preset": "paper"})),
        "10 observations.*2",
    ),
    *[
        (f"{k}_{name}", _poke(k, v), f"{k}.*(finite|NaN|inf)")
        for k in ("obs_mean", "obs_var", "w0", "b1", "w_out", "b_out", "obs_clip", "obs_eps")
        for name, v in (("nan", np.nan), ("inf", np.inf), ("-inf", -np.inf))
    ],
    ("obs_var_negative", _poke("obs_var", -1.0, 3), "obs_var.*> 0"),
    ("obs_var_zero", _poke("obs_var", 0.0, 3), "obs_var.*> 0"),
    ("obs_eps_negative", _set("obs_eps", -1e-8), "obs_eps.*≥ 0"),
    ("obs_clip_zero", _set("obs_clip", 0.0), "obs_clip.*> 0"),
    ("obs_clip_negative", _set("obs_clip", -10.0), "obs_clip.*> 0"),
    ("w0_complex", lambda a: {**a, "w0": a["w0"] + 1j}, "w0.*dtype"),
    ("w0_strings", lambda a: {**a, "w0": a["w0"].astype(str)}, "w0.*dtype"),
    ("b0_bool", lambda a: {**a, "b0": a["b0"] > 0}, "b0.*dtype"),
    ("obs_mean_datetime", _set("obs_mean", np.zeros(10, "datetime64[s]")), "obs_mean.*dtype"),
    ("meta_not_text", _set("meta", 1.0), "meta.*JSON text"),
    ("meta_bad_json", _set("meta", "{"), "meta.*JSON"),
    ("meta_a_list", _set("meta", "[]"), "meta.*object"),
    ("meta_nan", _set("meta", '{"env_kwargs": {"scale_limit": NaN}}'), "meta.*NaN"),
    ("meta_nested_deeply", _set("meta", "[" * 100_000 + "]" * 100_000), "meta.*nested"),
    (
        "env_kwargs_a_list",
        lambda a: _with_meta(a, lambda m: m.update(env_kwargs=[1])),
        "env_kwargs",
    ),
    (
        "env_kwargs_unknown_key",
        lambda a: _with_meta(a, lambda m: m["env_kwargs"].update(extra_s=1)),
        "extra_s",
    ),
    (
        "env_kwargs_bad_value",
        lambda a: _with_meta(a, lambda m: m["env_kwargs"].update(action={"scale_limit": 0.5})),
        r"action\.scale_limit must be",
    ),
    (
        "env_kwargs_flat_bad_value",  # a file of the first version, read by the legacy module
        lambda a: _with_meta(a, lambda m: m.update(env_kwargs={"extras": "yes"})),
        "meta env_kwargs: extras must be true or false",
    ),
    (
        "env_kwargs_flat_and_preset",
        lambda a: _with_meta(a, lambda m: m["env_kwargs"].update(split_q=True)),
        "mix the first version's flat keys",
    ),
]


def _zip(members: dict[str, bytes]) -> bytes:
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as z:
        for name, data in members.items():
            z.writestr(name, data)
    return buf.getvalue()


def _npy(array: np.ndarray) -> bytes:
    buf = io.BytesIO()
    np.save(buf, array)
    return buf.getvalue()


def _huge_header() -> bytes:
    """An .npy member whose header declares 8 GB of data (a few bytes follow)."""
    buf = io.BytesIO()
    np.lib.format.write_array_header_1_0(
        buf, {"descr": "<f8", "fortran_order": False, "shape": (10**9,)}
    )
    return buf.getvalue() + b"\0" * 64


def _npz(arrays: Arrays) -> bytes:
    buf = io.BytesIO()
    np.savez(buf, **arrays)  # type: ignore[arg-type]
    return buf.getvalue()


GOOD = DEFAULT_PPO.read_bytes()
RNG = np.random.default_rng(20)
#: Byte-level faults: (case, the file's bytes, the problem the message names).
BYTE_FAULTS: list[tuple[str, bytes, str]] = [
    ("empty", b"", "empty"),
    ("random_bytes", RNG.bytes(4096), "not an .npz"),
    ("text", b"obs_mean,obs_var\n1,2\n", "not an .npz"),
    ("npy_not_npz", _npy(np.zeros(10)), "not an .npz"),
    ("pickle", pickle.dumps({"obs_mean": [0.0]}), "not an .npz"),
    ("zip_magic_then_garbage", b"PK\x03\x04" + RNG.bytes(600), "corrupt"),
    *[
        (f"truncated_{n}", GOOD[:n], "corrupt|truncated")
        for n in (2, 4, 30, 200, len(GOOD) // 2, len(GOOD) - 1)
    ],
    ("flipped_payload", GOOD[:400] + bytes([GOOD[400] ^ 0xFF]) + GOOD[401:], "corrupt"),
    ("empty_zip", _zip({}), "missing"),
    ("zip_without_arrays", _zip({"readme.txt": b"hello"}), "readme.txt"),
    ("zip_of_garbage_npy", _zip({"obs_mean.npy": b"\x93NUMPY garbage"}), "obs_mean"),
    ("declared_8_gb", _zip({"obs_mean.npy": _huge_header()}), "obs_mean.*larger than"),
    (
        "object_array",
        _npz({**_shipped(), "obs_mean": np.array([object()], dtype=object)}),
        "obs_mean.*object|pickle",
    ),
]


def _refused(path: Path, problem: str) -> str:
    with pytest.raises(PolicyFileError) as info:
        NumpyPPOPolicy.load(path)
    return assert_one_line_error(info, str(path), patterns=(problem,))


@pytest.mark.parametrize(
    ("case", "mutate", "problem"), ARRAY_FAULTS, ids=[c[0] for c in ARRAY_FAULTS]
)
def test_malformed_arrays_are_refused_at_load(tmp_path, case, mutate, problem):
    path = tmp_path / f"{case}.npz"
    path.write_bytes(_npz(mutate(_shipped())))
    _refused(path, problem)
    # the same error through the names evaluate and train use
    with pytest.raises(PolicyFileError):
        policy_env_kwargs(f"ppo:{path}")


@pytest.mark.parametrize(("case", "data", "problem"), BYTE_FAULTS, ids=[c[0] for c in BYTE_FAULTS])
def test_broken_files_are_refused_at_load(tmp_path, case, data, problem):
    path = tmp_path / f"{case}.npz"
    path.write_bytes(data)
    _refused(path, problem)


def test_missing_file_directory_and_device(tmp_path):
    _refused(tmp_path / "missing.npz", "no such file")
    (tmp_path / "dir.npz").mkdir()
    _refused(tmp_path / "dir.npz", "directory")
    _refused(Path("/dev/zero"), "not a regular file")  # reading it would never end


class _Payload:
    """Unpickling this would create ``marker``: loading must never unpickle."""

    def __init__(self, marker: Path) -> None:
        self.marker = marker

    def __reduce__(self) -> tuple:
        return (Path.write_text, (self.marker, "executed"))


def test_nothing_in_a_policy_file_is_executed(tmp_path):
    marker = tmp_path / "marker"
    path = tmp_path / "evil.npz"
    np.savez(path, **{**_shipped(), "obs_mean": np.array([_Payload(marker)], dtype=object)})
    _refused(path, "obs_mean")
    raw = tmp_path / "evil_raw.npz"
    raw.write_bytes(pickle.dumps(_Payload(marker)))
    _refused(raw, "not an .npz")
    assert not marker.exists()


def test_oversized_member_is_refused_before_reading(tmp_path, monkeypatch):
    import agents.policies.policy_file as policy_file

    monkeypatch.setattr(policy_file, "MAX_ARRAY_BYTES", 20_000)
    path = tmp_path / "big.npz"
    path.write_bytes(_npz({**_shipped(), "w1": np.zeros((64, 64))}))
    _refused(path, "w1.*larger than")


@pytest.mark.parametrize("case", ["random_bytes", "truncated_200", "w0_nan", "b_out_short"])
def test_cli_evaluate_with_a_broken_policy_exits_2_with_one_line(tmp_path, capsys, case):
    path = tmp_path / f"{case}.npz"
    faults = {c: d for c, d, _ in BYTE_FAULTS}
    mutations = {c: m for c, m, _ in ARRAY_FAULTS}
    path.write_bytes(faults[case] if case in faults else _npz(mutations[case](_shipped())))
    args = [
        "evaluate",
        "--scenario",
        "nonstationary",
        "--policies",
        f"ppo:{path}",
        "--episodes",
        "1",
        "--out",
        str(tmp_path / "out"),
        "--quiet",
    ]
    assert main(args) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and str(path) in err and "Traceback" not in err
    assert not (tmp_path / "out").exists()


@settings(
    max_examples=examples(150),
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture],
)
@given(position=st.integers(0, len(GOOD) - 1), value=st.integers(0, 255))
def test_any_corrupted_byte_loads_or_is_refused(tmp_path, position, value):
    """A byte of the shipped file replaced: either the file still loads (the byte was padding
    or metadata that does not matter) and the policy predicts finite actions, or a one-line
    PolicyFileError — never another exception."""
    path = tmp_path / "fuzz.npz"
    path.write_bytes(GOOD[:position] + bytes([value]) + GOOD[position + 1 :])
    try:
        policy = NumpyPPOPolicy.load(path)
    except PolicyFileError as e:
        assert_one_line_error(e, str(path))
        return
    action, _ = policy.predict(np.zeros(policy.n_obs, np.float32))
    assert np.all(np.isfinite(action)) and np.all(np.abs(action) <= 1.0)


def test_predict_checks_the_observation_size_and_survives_extremes():
    policy = NumpyPPOPolicy.load(DEFAULT_PPO)
    with pytest.raises(ValueError, match=r"10 observations.*\(7,\)") as info:
        policy.predict(np.zeros(7, np.float32))
    assert_one_line_error(info)
    with pytest.raises(ValueError, match="10 observations"):
        policy.predict(np.zeros((4, 3), np.float32))
    extremes = np.array([1e308, -1e308, np.inf, -np.inf, 0.0, 8.0, -8.0, 1.0, -1.0, 3e38])
    for obs in (extremes, -extremes, np.stack([extremes, extremes[::-1]])):
        action, _ = policy.predict(obs)
        assert np.all(np.isfinite(action)) and np.all(np.abs(action) <= 1.0)


def test_a_valid_policy_still_loads_and_predicts_as_before():
    """The checks change nothing for a good file: the arrays are the file's, float64."""
    policy = NumpyPPOPolicy.load(DEFAULT_PPO)
    arrays = _shipped()
    np.testing.assert_array_equal(policy.mean, arrays["obs_mean"])
    np.testing.assert_array_equal(policy.std, np.sqrt(arrays["obs_var"] + arrays["obs_eps"]))
    obs = np.linspace(-2.0, 2.0, 10)
    x = np.clip(
        (obs - arrays["obs_mean"]) / np.sqrt(arrays["obs_var"] + arrays["obs_eps"]), -10.0, 10.0
    )
    for i in range(2):
        x = np.tanh(x @ arrays[f"w{i}"].T + arrays[f"b{i}"])
    want = np.clip(x @ arrays["w_out"].T + arrays["b_out"], -1, 1).astype(np.float32)
    np.testing.assert_array_equal(policy.predict(obs)[0], want)
    assert policy.env_kwargs == _meta(arrays)["env_kwargs"]


def test_make_policy_with_a_broken_file_is_an_aeromag_error(tmp_path):
    path = tmp_path / "p.npz"
    path.write_bytes(b"")
    with pytest.raises(AeromagError, match="empty"):
        make_policy(f"ppo:{path}", None)
