"""Sphinx extension of the aeromag_env site: writes the generated pages, resolves references.

* ``config-inited`` (before Sphinx lists the pages and autosummary reads them): the
  environment pages
  (``docs/environments/``), the API, command-line, flight-field and report.json references
  (``docs/reference/``), each written only when its text changed.
* ``missing-reference``: a docstring names an object by the module that defines it
  (``aeromag_env.environment.env.EnvConfig``), the API documents it under its public name
  (``aeromag_env.EnvConfig``): the reference goes there; a name that is not in the API goes to
  its module's entry on the module pages. A name that exists nowhere stays a warning (an error
  in the strict build).
"""

from __future__ import annotations

import importlib
import inspect
from pathlib import Path
from typing import Any

import docstrings
import gen_api
import gen_cli
import gen_envs
import gen_fields
import gen_report
import sections
from docutils import nodes
from sphinx.application import Sphinx
from sphinx.environment import BuildEnvironment

import aeromag_env

#: The root page's table of contents, found when the build starts.
_ROOT_ENTRIES: list[str] = []


def generate(app: Sphinx, config: Any = None) -> None:
    docs = Path(app.srcdir)
    reference = docs / "reference"
    gen_envs.write_all(docs / "environments")
    gen_api.write(reference)
    gen_cli.write(reference)
    gen_fields.write(reference)
    gen_report.write(reference, Path(app.outdir).parent / ".report-cache")
    _ROOT_ENTRIES[:] = sections.write_section_pages(docs)


def add_toctrees(app: Sphinx, docname: str, source: list[str]) -> None:
    """The root page's sections, and a hidden table of contents in each section index."""
    if docname == "index":
        source[0] = source[0].replace(sections.MARKER, sections.root_toctree(_ROOT_ENTRIES))
        return
    extra = sections.folder_toctree(docname, Path(app.srcdir))
    if extra:
        source[0] += extra


def _locate(target: str) -> tuple[Any, str] | None:
    """The object a dotted name points at, and the longest importable module of that name."""
    parts = target.split(".")
    for cut in range(len(parts), 0, -1):
        modname = ".".join(parts[:cut])
        try:
            obj: Any = importlib.import_module(modname)
        except ImportError:
            continue
        except Exception:
            return None
        try:
            for attr in parts[cut:]:
                obj = getattr(obj, attr)
        except AttributeError:
            return None
        return obj, modname
    return None


def _public_name(obj: Any, rest: list[str]) -> str | None:
    """``aeromag_env.NAME`` or an ``agents`` name documented for the same object."""
    for name in aeromag_env.__all__:
        if name not in gen_api.DATA_NAMES and getattr(aeromag_env, name) is obj:
            return ".".join(["aeromag_env", name, *rest])
    for modname, names in gen_api.agents_public().items():
        module = importlib.import_module(modname)
        for name in names:
            if getattr(module, name) is obj:
                return ".".join([modname, name, *rest])
    return None


def resolve(
    app: Sphinx, env: BuildEnvironment, node: Any, contnode: nodes.Element
) -> nodes.Element | None:
    if node.get("refdomain") != "py":
        return None
    domain: Any = env.get_domain("py")
    target = "".join(node["reftarget"].split())  # a name wrapped over two docstring lines
    for candidate in _candidates(target, node):
        found = _locate(candidate)
        rest: list[str] = []
        if found is None and "." in candidate:  # a member set in __init__: its class
            holder, _, member = candidate.rpartition(".")
            found = _locate(holder)
            if found is None or not inspect.isclass(found[0]):
                continue
            candidate, rest = holder, [member]
        if found is None:
            continue
        public = _public_name(found[0], rest if not rest else [])
        if public and public != candidate:
            ref = domain.resolve_xref(
                env, node["refdoc"], app.builder, "obj", public, node, contnode
            )
            if ref is not None:
                return ref
        return domain.resolve_xref(
            env, node["refdoc"], app.builder, "mod", found[1], node, contnode
        )
    return None


def _candidates(target: str, node: Any) -> list[str]:
    """Full names ``target`` may mean: as written, in the context module and class, and in the
    module that defines the documented object (an API page documents ``aeromag_env.Flight``,
    whose docstring names its neighbours in ``aeromag_env.flight.data``)."""
    module, cls = node.get("py:module"), node.get("py:class")
    out = [target]
    # the context module and the packages above it (a package's docstring names its modules'
    # functions, a module's names its package's)
    homes = (
        [".".join(module.split(".")[:i]) for i in range(module.count(".") + 1, 0, -1)]
        if module
        else []
    )
    documented = node.get("refdoc", "").rsplit("/", 1)[-1]
    for context in (f"{module}.{cls}" if module and cls else None, documented):
        found = _locate(context) if context else None
        if found is not None and getattr(found[0], "__module__", None):
            homes.append(found[0].__module__)
            if inspect.isclass(found[0]):
                homes.append(f"{found[0].__module__}.{found[0].__qualname__}")
    for home in homes:
        out.append(f"{home}.{target}")
        if cls:
            out.append(f"{home}.{cls}.{target}")
    return list(dict.fromkeys(out))


def setup(app: Sphinx) -> dict[str, Any]:
    # config-inited: before Sphinx lists the source files (autosummary reads that list)
    app.connect("config-inited", generate)
    app.connect("source-read", add_toctrees)
    # before numpydoc (priority 500) parses the sections
    app.connect("autodoc-process-docstring", docstrings.process, priority=100)
    app.connect("missing-reference", resolve)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
