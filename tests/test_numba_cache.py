"""numba's cache keyed on every compiled module (aeromag_env.numba_cache)."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

from aeromag_env.compensation import kalman_batch, kernels
from aeromag_env.environment import kernels as env_kernels
from aeromag_env.numba_cache import MARKER, PACKAGE, PackageLocator, compiled_sources_digest

ROOT = Path(__file__).resolve().parents[1]

# a package of two files: g (in a.py) calls, and numba inlines, f (in b.py)
INIT = """import os
from pathlib import Path
from aeromag_env.numba_cache import install
if os.environ.get("KEYED"):
    install(Path(__file__).parent)
"""
A = """from aeromag_env.numba_cache import njit
from pkgx.b import f
@njit(cache=True)
def g():
    return f()
"""
B = """from aeromag_env.numba_cache import njit
@njit(cache=True)
def f():
    return {value}
"""
RUN = "import pkgx.a as a; v = a.g(); print(v, a.g.stats.cache_hits.most_common(1))"


def _package(folder: Path, value: int) -> None:
    pkg = folder / "pkgx"
    pkg.mkdir(exist_ok=True)
    (pkg / "__init__.py").write_text(INIT)
    (pkg / "a.py").write_text(A)
    (pkg / "b.py").write_text(B.format(value=value))


def _g(folder: Path, keyed: bool) -> str:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(folder), str(ROOT)])}
    env.pop("NUMBA_CACHE_DIR", None)
    env.pop("NUMBA_DISABLE_CACHE", None)
    if keyed:
        env["KEYED"] = "1"
    else:
        env.pop("KEYED", None)
    done = subprocess.run([sys.executable, "-c", RUN], cwd=folder, env=env, text=True,
                          capture_output=True, timeout=300, check=True)  # fmt: skip
    return done.stdout.strip()


def test_a_change_to_a_called_module_reaches_the_caller_through_the_cache(tmp_path):
    """The hazard the module exists for: g's cache entry holds f's code, and numba checks only
    a.py; keyed on the package's compiled modules, a changed b.py recompiles g. The cache is
    used at all (a hit on the second run), and without the key numba serves the old f."""
    keyed, plain = tmp_path / "keyed", tmp_path / "plain"
    for folder in (keyed, plain):
        folder.mkdir()
        _package(folder, 1)
    assert _g(keyed, True).startswith("1 [")
    assert _g(keyed, True).startswith("1 [(()")  # loaded from the cache: a hit
    _package(keyed, 2)
    assert _g(keyed, True).startswith("2 ")
    assert _g(plain, False).startswith("1 ")
    _package(plain, 2)
    assert _g(plain, False).startswith("1 "), "numba now sees f's change itself"


def test_the_package_kernels_get_the_package_locator():
    for dispatcher in (kernels.advance, kalman_batch._advance_range, env_kernels.env_step):
        locator = dispatcher._cache._impl.locator
        assert isinstance(locator, PackageLocator)
        _own, digest = locator.get_source_stamp()
        assert digest == compiled_sources_digest() and len(digest) == 64


def test_the_digest_follows_compiled_modules_only(tmp_path):
    digest = compiled_sources_digest.__wrapped__
    (tmp_path / "k.py").write_text(MARKER.decode() + "\nX = 1\n")
    (tmp_path / "plain.py").write_text("Y = 1\n")
    first = digest(tmp_path)
    (tmp_path / "plain.py").write_text("Y = 2\n")
    assert digest(tmp_path) == first
    (tmp_path / "k.py").write_text(MARKER.decode() + "\nX = 2\n")
    assert digest(tmp_path) != first


def test_every_kernel_module_compiles_through_numba_cache():
    """No module takes njit (or jit) straight from numba: its functions would miss the key."""
    direct = re.compile(r"from numba import .*\bn?jit\b|\bnumba\.n?jit\b")
    offenders = [
        str(path.relative_to(PACKAGE))
        for path in PACKAGE.rglob("*.py")
        if path.name != "numba_cache.py" and direct.search(path.read_text())
    ]
    assert offenders == []
    users = [p for p in PACKAGE.rglob("*.py") if MARKER in p.read_bytes()]
    assert len(users) >= 10  # the compensation, environment and discovery kernels
