"""numba's cache keyed on every compiled module (aeromag_env.numba_cache)."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from aeromag_env.compensation import kalman_batch, kernels
from aeromag_env.environment import kernels as env_kernels
from aeromag_env.numba_cache import (
    MARKER,
    PACKAGE,
    PackageLocator,
    compiled_sources,
    compiled_sources_digest,
)

ROOT = Path(__file__).resolve().parents[1]

# a package: g (in a.py) calls, and numba inlines, f (in b.py), which reads a constant of c.py
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
from pkgx.c import OFFSET
@njit(cache=True)
def f():
    return {value} + OFFSET
"""
RUN = "import pkgx.a as a; print(a.g(), a.g.stats.cache_hits.most_common(1))"


def _package(folder: Path, value: int, offset: int = 0) -> None:
    pkg = folder / "pkgx"
    pkg.mkdir(exist_ok=True)
    (pkg / "__init__.py").write_text(INIT)
    (pkg / "a.py").write_text(A)
    (pkg / "b.py").write_text(B.format(value=value))
    (pkg / "c.py").write_text(f"OFFSET = {offset}\n")  # a constant, compiled into f and g


def _g(folder: Path, keyed: bool) -> str:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(folder), str(ROOT)])}
    env.pop("NUMBA_CACHE_DIR", None)
    env.pop("NUMBA_DISABLE_CACHE", None)
    if keyed:
        env["KEYED"] = "1"
    else:
        env.pop("KEYED", None)
    done = subprocess.run(
        [sys.executable, "-c", RUN],
        cwd=folder,
        env=env,
        text=True,
        capture_output=True,
        timeout=300,
        check=True,
    )
    return done.stdout.strip()


@pytest.mark.slow
def test_a_change_to_a_called_module_reaches_the_caller_through_the_cache(tmp_path):
    """The hazard the module exists for: g's cache entry holds f's code and c's constant, and
    numba checks only a.py; keyed on the compiled modules and what they import, a changed b.py
    or c.py recompiles g. The cache is used (a hit on the second run); without the key numba
    serves the old f."""
    keyed, plain = tmp_path / "keyed", tmp_path / "plain"
    for folder in (keyed, plain):
        folder.mkdir()
        _package(folder, 1)
    assert _g(keyed, True).startswith("1 [")
    assert _g(keyed, True).startswith("1 [(()")  # loaded from the cache: a hit
    _package(keyed, 2)
    assert _g(keyed, True).startswith("2 ")
    _package(keyed, 2, offset=10)
    assert _g(keyed, True).startswith("12 ")
    assert _g(plain, False).startswith("1 ")
    _package(plain, 2)
    assert _g(plain, False).startswith("1 "), "numba now sees f's change itself"


def test_the_package_kernels_get_the_package_locator():
    for dispatcher in (kernels.advance, kalman_batch._advance_range, env_kernels.env_step):
        locator = dispatcher._cache._impl.locator
        assert isinstance(locator, PackageLocator)
        _own, digest = locator.get_source_stamp()
        assert digest == compiled_sources_digest(locator.root) and len(digest) == 64


def test_the_digest_follows_compiled_modules_and_their_imports_only(tmp_path):
    root = tmp_path / "pkgx"
    root.mkdir()
    (root / "__init__.py").write_text("")
    (root / "k.py").write_text(MARKER.decode() + "\nfrom pkgx import layout\nX = 1\n")
    (root / "layout.py").write_text("from pkgx.sub.deep import (\n    A,  # a comment\n)\n")
    (root / "sub").mkdir()
    (root / "sub" / "deep.py").write_text("A = 1\n")
    (root / "plain.py").write_text("Y = 1\n")
    assert {p.relative_to(root).as_posix() for p in compiled_sources(root)} == {
        "__init__.py",
        "k.py",
        "layout.py",
        "sub/deep.py",
    }
    digest = compiled_sources_digest.__wrapped__
    first = digest(root)
    (root / "plain.py").write_text("Y = 2\n")
    assert digest(root) == first
    for path in ("k.py", "sub/deep.py"):
        (root / path).write_text((root / path).read_text() + "Z = 3\n")
        assert digest(root) != first
        first = digest(root)


def test_the_package_digest_covers_the_layouts_the_kernels_read():
    names = {p.relative_to(PACKAGE).as_posix() for p in compiled_sources()}
    assert {
        "compensation/kernel_layout.py",
        "environment/spaces.py",
        "simulation/interference.py",
        "compensation/model.py",
    } <= names
    assert "cli/main.py" not in names and "flight/files.py" not in names


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
