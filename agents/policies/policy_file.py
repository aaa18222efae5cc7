"""Read an exported policy file (``.npz``) and check all of it before anything runs it.

The layout (written by :func:`export_policy` for PPO and by :func:`export_actor` for the other
learners): ``obs_mean`` and ``obs_var`` (n_obs,), the scalars ``obs_clip`` and ``obs_eps``,
optionally an LSTM layer (a recurrent policy: ``lstm_w_ih`` (4H, n_obs), ``lstm_w_hh`` (4H, H),
``lstm_b`` (4H,), torch's gate order i, f, g, o, the two biases summed), hidden layers ``w0``
(h0, n_in), ``b0`` (h0,), ``w1`` (h1, h0), … and the action layer ``w_out`` (n_act, h_last),
``b_out`` (n_act,), all real numbers; ``meta`` a JSON object as a 0-d string array, whose
``activation`` (of the hidden layers: :data:`ACTIVATIONS`, default ``tanh``) and ``head``
(:data:`HEADS`: ``clip`` the action layer's output to [-1, 1], PPO's deterministic action, or
``tanh`` it, SAC's; default ``clip``) say how to run it, and whose ``env_kwargs`` (the
settings of an :class:`~aeromag_env.environment.config.EnvConfig`: the shipped files name a
preset, ``{"preset": "general"}``; files written by the environment's first version carry
its flat keys, which are read as today's settings by
:func:`aeromag_env.environment.legacy.upgrade`: the loaded ``meta`` holds them in today's
terms) must give n_obs observations and n_act actions. Nothing is unpickled
(``allow_pickle=False``), member sizes are checked before a member is read, and every problem
is a one-line :class:`~aeromag_env.errors.PolicyFileError` naming the file and the problem.
"""

from __future__ import annotations

import json
import math
import re
import zipfile
from pathlib import Path
from typing import Any

import numpy as np

from aeromag_env.atomic import atomic_path
from aeromag_env.configs import from_dict
from aeromag_env.environment.env import EnvConfig
from aeromag_env.environment.legacy import upgrade
from aeromag_env.environment.spaces import action_size, observation_names
from aeromag_env.errors import ConfigError, PolicyFileError

#: Largest uncompressed array [bytes]: the shipped policy's largest is 33 kB; a bound keeps a
#: hostile archive (a zip bomb) from filling the memory.
MAX_ARRAY_BYTES = 64 * 2**20
#: Most members an archive may have (the shipped policy has 11).
MAX_MEMBERS = 256
#: Largest magnitude of a stored value: a trained network's values are O(1); beyond this the
#: products of predict could overflow to inf − inf = NaN.
MAX_ABS = 1e100
SCALARS = ("obs_clip", "obs_eps")
REQUIRED = ("obs_mean", "obs_var", *SCALARS, "w_out", "b_out", "meta")
#: The arrays of a recurrent policy's LSTM layer (all three, or none).
LSTM = ("lstm_w_ih", "lstm_w_hh", "lstm_b")
#: The hidden layers' activation functions and the output heads a file may name in ``meta``.
ACTIVATIONS = ("tanh", "relu")
HEADS = ("clip", "tanh")
_HIDDEN = re.compile(r"([wb])(\d+)")
_ZIP_MAGIC = (b"PK\x03\x04", b"PK\x05\x06")  # an archive's first member; an empty archive
#: What reading a broken archive raises: zipfile, zlib and numpy's .npy header parser raise
#: many kinds (BadZipFile, EOFError, zlib.error, ValueError, SyntaxError and
#: tokenize.TokenError from the header's literal, TypeError from its dtype, ...): for bytes
#: from a file, any of them means a corrupt file.
_READ_ERRORS = (Exception,)


class _Problem(Exception):
    """What is wrong with the file (becomes the tail of the PolicyFileError)."""


def read_policy(path: str | Path) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
    """The arrays (float64) and the metadata of the policy file ``path``, checked.

    Raises
    ------
    PolicyFileError
        One line: ``cannot load policy PATH: problem``.
    """
    path = Path(path)
    try:
        arrays = _read_arrays(path)
        meta = _meta(arrays.pop("meta"))
        numbers = {k: _real(k, v) for k, v in arrays.items()}
        _check_layers(numbers, meta)
        _check_values(numbers)
    except _Problem as e:
        raise PolicyFileError(f"cannot load policy {path}: {e}") from None
    return numbers, meta


def _read_arrays(path: Path) -> dict[str, np.ndarray]:
    _check_head(path)
    try:
        with zipfile.ZipFile(path) as z:
            infos = z.infolist()
            if len(infos) > MAX_MEMBERS:
                raise _Problem(f"{len(infos)} members; a policy has at most {MAX_MEMBERS}")
            for info in infos:
                _check_size(z, info)
        with np.load(path, allow_pickle=False) as data:
            arrays = {k: _member(data, k) for k in data.files}
    except _Problem:
        raise
    except _READ_ERRORS as e:
        raise _Problem(f"corrupt .npz archive ({type(e).__name__}: {e})") from None
    _check_names(arrays)
    return arrays


def _check_head(path: Path) -> None:
    if path.exists() and not path.is_file() and not path.is_dir():  # a device or a pipe
        raise _Problem("not a regular file")
    try:
        with path.open("rb") as f:
            head = f.read(4)
    except OSError as e:
        raise _Problem(str(e.strerror or e).lower()) from None
    if not head:
        raise _Problem("the file is empty")
    if head not in _ZIP_MAGIC:
        if len(head) < 4 and _ZIP_MAGIC[0].startswith(head):
            raise _Problem("truncated .npz archive")
        raise _Problem(
            "not an .npz archive (a policy file is the .npz that `aeromag train` writes)"
        )


def _check_size(z: zipfile.ZipFile, info: zipfile.ZipInfo) -> None:
    """Refuse a member larger than :data:`MAX_ARRAY_BYTES`, by its stored size and by the shape
    its .npy header declares, before numpy allocates the array."""
    name = info.filename.removesuffix(".npy")
    size = info.file_size
    if size <= MAX_ARRAY_BYTES and info.filename.endswith(".npy"):
        try:
            with z.open(info) as f:
                version = np.lib.format.read_magic(f)
                read = (
                    np.lib.format.read_array_header_1_0
                    if version == (1, 0)
                    else np.lib.format.read_array_header_2_0
                )
                shape, _, dtype = read(f)
        except _READ_ERRORS as e:
            raise _Problem(f"{name} is corrupt or not a .npy array ({e})") from None
        size = math.prod(shape) * dtype.itemsize
    if size > MAX_ARRAY_BYTES:
        raise _Problem(f"{name} is larger than {MAX_ARRAY_BYTES} bytes ({size})")


def _member(data: Any, key: str) -> np.ndarray:
    try:
        value = data[key]
    except ValueError as e:
        if "allow_pickle" in str(e):
            raise _Problem(f"{key} holds Python objects (pickled data is never loaded)") from None
        raise _Problem(f"{key} is corrupt or not a .npy array ({e})") from None
    except _READ_ERRORS as e:
        raise _Problem(f"{key} is corrupt ({type(e).__name__}: {e})") from None
    if not isinstance(value, np.ndarray):
        raise _Problem(f"{key} is not a .npy array")
    return value


def _check_names(arrays: dict[str, np.ndarray]) -> None:
    names = set(arrays)
    hidden = {k for k in names if _HIDDEN.fullmatch(k)}
    missing = [k for k in REQUIRED if k not in names]
    if missing:
        held = ", ".join(sorted(names)) or "none"
        raise _Problem(f"missing arrays {', '.join(missing)} (the file holds {held})")
    unexpected = sorted(names - hidden - set(REQUIRED) - set(LSTM))
    if unexpected:
        raise _Problem(f"unexpected arrays {', '.join(unexpected)}")
    lstm = [k for k in LSTM if k in names]
    if lstm and len(lstm) != len(LSTM):
        missing_lstm = ", ".join(k for k in LSTM if k not in names)
        raise _Problem(f"an LSTM layer needs {', '.join(LSTM)}; {missing_lstm} missing")
    for k in sorted(hidden):
        twin = ("b" if k[0] == "w" else "w") + k[1:]
        if twin not in names:
            raise _Problem(f"{k} without {twin} (hidden layer {k[1:]} needs both)")
    n = len(hidden) // 2
    if hidden != {f"{wb}{i}" for wb in "wb" for i in range(n)}:
        got = ", ".join(sorted(k for k in hidden if k[0] == "w"))
        raise _Problem(f"hidden layers must be numbered w0, w1, … without gaps; got {got}")


def _meta(value: np.ndarray) -> dict[str, Any]:
    if value.dtype.kind != "U" or value.shape != ():
        raise _Problem(
            f"meta must be JSON text (a 0-d string array), got {value.dtype} of shape {value.shape}"
        )
    try:
        meta = json.loads(str(value), parse_constant=_no_constant)
    except ValueError as e:
        raise _Problem(f"meta is not valid JSON: {e}") from None
    except RecursionError:
        raise _Problem("meta is nested too deeply") from None
    if not isinstance(meta, dict):
        raise _Problem(f"meta must be a JSON object, got {type(meta).__name__}")
    kwargs = meta.get("env_kwargs", {})
    if not isinstance(kwargs, dict):
        raise _Problem(f"meta env_kwargs must be a JSON object, got {type(kwargs).__name__}")
    try:
        meta["env_kwargs"] = upgrade(kwargs)  # a file of the first version: its flat keys
        from_dict(EnvConfig, meta["env_kwargs"])
    except ConfigError as e:
        raise _Problem(f"meta env_kwargs: {e}") from None
    for key, valid in (("activation", ACTIVATIONS), ("head", HEADS)):
        if meta.get(key, valid[0]) not in valid:
            raise _Problem(f"meta {key} must be one of {', '.join(valid)}, got {meta[key]!r}")
    return meta


def _no_constant(name: str) -> Any:
    raise ValueError(f"{name} is not a JSON number")


def _real(key: str, value: np.ndarray) -> np.ndarray:
    if value.dtype.kind not in "fiu":
        raise _Problem(f"{key} has dtype {value.dtype}; expected real numbers (float64)")
    return value.astype(np.float64)


def _check_layers(arrays: dict[str, np.ndarray], meta: dict[str, Any]) -> None:
    """Shapes: observations → hidden layers → actions, and the sizes ``env_kwargs`` give."""
    mean = arrays["obs_mean"]
    if mean.ndim != 1 or mean.size < 1:
        raise _Problem(f"obs_mean has shape {mean.shape}; expected (n_obs,) with n_obs ≥ 1")
    n_obs = mean.size
    _shape(arrays, "obs_var", (n_obs,))
    for k in SCALARS:
        if arrays[k].shape != ():
            raise _Problem(f"{k} must be a scalar, got shape {arrays[k].shape}")
    width, prev = n_obs, "an observation has"
    if "lstm_w_ih" in arrays:
        hidden = arrays["lstm_w_hh"].shape[-1] if arrays["lstm_w_hh"].ndim == 2 else 0
        if hidden < 1:
            raise _Problem(f"lstm_w_hh has shape {arrays['lstm_w_hh'].shape}; expected (4H, H)")
        _shape(arrays, "lstm_w_ih", (4 * hidden, n_obs))
        _shape(arrays, "lstm_w_hh", (4 * hidden, hidden))
        _shape(arrays, "lstm_b", (4 * hidden,))
        width, prev = hidden, "the LSTM gives"
    for i in range(sum(1 for k in arrays if k.startswith("w") and k[1:].isdigit())):
        width, prev = _layer(arrays, f"w{i}", f"b{i}", width, prev), f"w{i} gives"
    n_act = _layer(arrays, "w_out", "b_out", width, prev)
    cfg = from_dict(EnvConfig, meta.get("env_kwargs", {}))
    want_obs, want_act = len(observation_names(cfg)), action_size(cfg)
    if n_obs != want_obs:
        raise _Problem(f"the policy takes {n_obs} observations but its env_kwargs give {want_obs}")
    if n_act != want_act:
        raise _Problem(f"the policy gives {n_act} actions but its env_kwargs take {want_act}")


def _layer(arrays: dict[str, np.ndarray], w: str, b: str, width: int, prev: str) -> int:
    """Check the layer ``w`` (units, width) and ``b`` (units,); return its units."""
    shape = arrays[w].shape
    if len(shape) != 2 or shape[1] != width or shape[0] < 1:
        raise _Problem(f"{w} has shape {shape}; expected (units, {width}) ({prev} {width} values)")
    _shape(arrays, b, (shape[0],))
    return int(shape[0])


def _shape(arrays: dict[str, np.ndarray], key: str, want: tuple) -> None:
    if arrays[key].shape != want:
        raise _Problem(f"{key} has shape {arrays[key].shape}; expected {want}")


def _check_values(arrays: dict[str, np.ndarray]) -> None:
    for k, v in arrays.items():
        if not np.all(np.isfinite(v)):
            raise _Problem(f"{k} holds non-finite values (NaN or inf)")
        if np.any(np.abs(v) > MAX_ABS):
            raise _Problem(f"{k} holds values beyond ±{MAX_ABS:g}")
    lowest = {k: float(np.min(arrays[k])) for k in ("obs_var", "obs_eps", "obs_clip")}
    if lowest["obs_var"] <= 0.0:
        raise _Problem(f"obs_var (observation variances) must be > 0, got {lowest['obs_var']}")
    if lowest["obs_eps"] < 0.0:
        raise _Problem(f"obs_eps must be ≥ 0, got {lowest['obs_eps']}")
    if lowest["obs_clip"] <= 0.0:
        raise _Problem(f"obs_clip must be > 0, got {lowest['obs_clip']}")


def export_policy(model: Any, venv: Any, path: Path, meta: dict[str, Any]) -> Path:
    """Write a stable-baselines3 PPO actor (``model``) and the observation statistics of its
    ``VecNormalize`` (``venv``) as a plain ``.npz`` in the layout above, atomically."""
    policy = model.policy
    arrays = {**_statistics(venv), **_linears(policy.mlp_extractor.policy_net, policy.action_net)}
    return write_policy(arrays, meta, path)


def export_actor(model: Any, venv: Any, path: Path, meta: dict[str, Any]) -> Path:
    """Write the deterministic actor of a stable-baselines3 or sb3-contrib model in the layout
    above: SAC and TQC (ReLU layers, ``tanh`` head: their squashed Gaussian's mean), or
    RecurrentPPO (its actor LSTM, then tanh layers, ``clip`` head); PPO as
    :func:`export_policy`. ``meta`` gains ``activation``, ``head`` and ``learner``."""
    policy, kind = model.policy, type(model).__name__
    if kind in ("SAC", "TQC"):
        arrays = _linears(policy.actor.latent_pi, policy.actor.mu)
        meta = {**meta, "activation": "relu", "head": "tanh"}
    elif kind == "RecurrentPPO":
        lstm = policy.lstm_actor
        if lstm.num_layers != 1:
            raise ValueError(f"the export takes a one-layer LSTM, got {lstm.num_layers} layers")
        arrays = {
            "lstm_w_ih": _numpy(lstm.weight_ih_l0),
            "lstm_w_hh": _numpy(lstm.weight_hh_l0),
            "lstm_b": _numpy(lstm.bias_ih_l0) + _numpy(lstm.bias_hh_l0),
            **_linears(policy.mlp_extractor.policy_net, policy.action_net),
        }
        meta = {**meta, "activation": "tanh", "head": "clip"}
    elif kind == "PPO":
        arrays = _linears(policy.mlp_extractor.policy_net, policy.action_net)
        meta = {**meta, "activation": "tanh", "head": "clip"}
    else:
        raise ValueError(f"no numpy export for {kind} (SAC, TQC, RecurrentPPO or PPO)")
    return write_policy({**_statistics(venv), **arrays}, {**meta, "learner": kind}, path)


def write_policy(arrays: dict[str, np.ndarray], meta: dict[str, Any], path: Path) -> Path:
    """Write ``arrays`` (the layout above, without ``meta``) and ``meta`` atomically."""
    out = {k: np.asarray(v, dtype=np.float64) for k, v in arrays.items()}
    with atomic_path(path) as tmp, open(tmp, "wb") as fh:
        np.savez(fh, **out, meta=np.array(json.dumps(meta)))  # type: ignore[arg-type]
    return path


def _statistics(venv: Any) -> dict[str, np.ndarray]:
    """The observation normalisation of a ``VecNormalize``."""
    return {
        "obs_mean": venv.obs_rms.mean.astype(np.float64),
        "obs_var": venv.obs_rms.var.astype(np.float64),
        "obs_clip": np.array(venv.clip_obs, dtype=np.float64),
        "obs_eps": np.array(venv.epsilon, dtype=np.float64),
    }


def _linears(hidden: Any, out: Any) -> dict[str, np.ndarray]:
    """The Linear layers of the torch module ``hidden`` as ``w0, b0, …`` and ``out`` as
    ``w_out, b_out``."""
    arrays = {"w_out": _numpy(out.weight), "b_out": _numpy(out.bias)}
    for i, layer in enumerate(m for m in hidden if hasattr(m, "weight")):
        arrays[f"w{i}"], arrays[f"b{i}"] = _numpy(layer.weight), _numpy(layer.bias)
    return arrays


def _numpy(tensor: Any) -> np.ndarray:
    return tensor.detach().cpu().numpy().astype(np.float64)
