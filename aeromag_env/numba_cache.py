"""numba's ``njit``, with its on-disk cache keyed on every compiled module of the package.

numba caches a compiled function under a stamp of the one file that defines it. Our kernels call,
and inline, compiled functions of other files (``environment.kernels.env_step`` runs
``compensation.kernels.advance``, which runs ``window``, ``consistency``, ``adaptive_rules``…),
and that code is compiled into the caller's cache entry. Edit one of those files, or check out a
commit that changes only it, and the caller's entry still matches its own file: numba loads the
old machine code and the change silently does not run (after an edit of
``compensation/kernels.py`` the batched filter, ``kalman_batch._advance_range``, would go on
with the old update while the single-flight filter ran the new one).

Importing :func:`njit` from here instead of from numba puts :class:`PackageLocator` in front
of numba's cache locators: for a function defined in this package it keeps numba's own choice
(cache folder, file names) and adds to the stamp a digest of the modules that compile code and
of every module of the package they import (:func:`compiled_sources`: their constants are
compiled in too), so a change to any of them recompiles all compiled code. Functions of other
packages are left to numba as before.
"""

from __future__ import annotations

import functools
import hashlib
import re
import warnings
from pathlib import Path
from typing import Any

from numba import njit
from numba.core import caching

__all__ = [
    "MARKER",
    "PACKAGE",
    "PackageLocator",
    "compiled_sources",
    "compiled_sources_digest",
    "install",
    "njit",
]

#: How a module that compiles code imports :func:`njit` (the digest starts from these).
MARKER = b"from aeromag_env.numba_cache import njit"
#: The folder of this package: the functions defined under it get :class:`PackageLocator`.
PACKAGE = Path(__file__).resolve().parent


@functools.cache
def compiled_sources_digest(root: Path = PACKAGE) -> str:
    """SHA-256 over the relative path and contents of :func:`compiled_sources` of ``root``,
    in path order."""
    digest = hashlib.sha256()
    for path in sorted(compiled_sources(root)):
        digest.update(path.relative_to(root).as_posix().encode() + b"\0")
        digest.update(hashlib.sha256(path.read_bytes()).digest())
    return digest.hexdigest()


def compiled_sources(root: Path = PACKAGE) -> set[Path]:
    """The ``.py`` files under ``root`` whose code can end up in a compiled function: those
    that compile with :func:`njit` from here (:data:`MARKER`) and every module of the package
    they import, directly or not (numba compiles the constants it reads — layouts, enum
    values — into the machine code as well)."""
    todo = [path for path in root.rglob("*.py") if MARKER in path.read_bytes()]
    found: set[Path] = set()
    while todo:
        path = todo.pop()
        if path not in found:
            found.add(path)
            todo.extend(_imported(path, root))
    return found


def _imported(path: Path, root: Path) -> list[Path]:
    """The files of the package under ``root`` that the module ``path`` imports: absolute
    imports by the package's name; ``from package.sub import name`` counts ``package.sub``
    and, if it is one, the module ``package.sub.name``. Read with patterns, not parsed: every
    process that compiles or loads a kernel runs this (~20 ms for the whole package)."""
    text = path.read_text(encoding="utf-8")
    package = re.escape(root.name)
    names = re.findall(rf"^\s*import\s+({package}(?:\.\w+)*)", text, re.MULTILINE)
    pattern = rf"^\s*from\s+({package}(?:\.\w+)*)\s+import\s+(\([^)]*\)|[^\n]*)"
    for module, imported in re.findall(pattern, text, re.MULTILINE):
        names.append(module)
        for item in imported.strip("()").split(","):
            name = item.split("#")[0].split(" as ")[0].strip()
            if name.isidentifier():
                names.append(f"{module}.{name}")
    files = []
    for name in names:
        base = root.joinpath(*name.split(".")[1:])
        files += [f for f in (base.with_suffix(".py"), base / "__init__.py") if f.is_file()]
    return files


class PackageLocator(caching._CacheLocator):
    """The cache locator numba would choose for a function (``inner``), its source stamp
    extended by :func:`compiled_sources_digest` of :attr:`root`."""

    root: Path = PACKAGE

    def __init__(self, inner: Any) -> None:
        self._inner = inner

    def ensure_cache_path(self) -> None:
        self._inner.ensure_cache_path()

    def get_cache_path(self) -> str:
        return str(self._inner.get_cache_path())

    def get_disambiguator(self) -> str:
        return str(self._inner.get_disambiguator())

    def get_source_stamp(self) -> Any:
        return self._inner.get_source_stamp(), compiled_sources_digest(self.root)

    @classmethod
    def from_function(cls, py_func: Any, py_file: str) -> PackageLocator | None:
        """A locator for ``py_func`` if ``py_file`` is under :attr:`root`, else None (numba
        goes on to its own locators)."""
        try:
            Path(py_file).resolve().relative_to(cls.root)
        except (OSError, ValueError):
            return None
        for other in _locator_classes():
            if isinstance(other, type) and issubclass(other, PackageLocator):
                continue
            inner = other.from_function(py_func, py_file)
            if inner is not None:
                return cls(inner)
        return None


def _locator_classes() -> list[Any]:
    """numba's list of cache locator classes, tried in order (on ``CacheImpl``, in older
    versions ``_CacheImpl``; AttributeError if neither)."""
    impl = getattr(caching, "CacheImpl", None) or getattr(caching, "_CacheImpl")  # noqa: B009
    classes: list[Any] = impl._locator_classes
    return classes


def install(root: Path = PACKAGE) -> type[PackageLocator]:
    """Put a :class:`PackageLocator` for the functions under ``root`` first among numba's cache
    locators (once per root); returns its class. Where numba lacks the hooks (a future
    version), warns that compiled code may go stale instead of failing."""
    root = Path(root).resolve()
    try:
        classes = _locator_classes()
    except AttributeError:
        warnings.warn(
            "this numba version has no cache locator hooks: compiled code is cached per file "
            "only; clear the __pycache__ folders after changing a kernel",
            RuntimeWarning,
            stacklevel=2,
        )
        return PackageLocator
    for cls in classes:
        if isinstance(cls, type) and issubclass(cls, PackageLocator) and cls.root == root:
            return cls
    locator = type(
        f"PackageLocator_{root.name}", (PackageLocator,), {"root": root, "__module__": __name__}
    )
    classes.insert(0, locator)
    return locator


install()
