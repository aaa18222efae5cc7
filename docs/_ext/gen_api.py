"""The Python API reference: every name of ``aeromag_env.__all__`` and the public names of
``agents``, grouped by stage, and a page per subpackage with each module's docstring.

The API page lists names through ``autosummary`` (one generated page per name, from its
numpydoc docstring); the module pages make every ``:mod:`` reference of the docstrings a link.
"""

from __future__ import annotations

import importlib
import inspect
import pkgutil
from pathlib import Path
from types import ModuleType
from typing import Any

from rst import heading, indent, literal, remove_stale, text, write_if_changed

import aeromag_env
import agents

#: Names documented as data (values, not docstrings) rather than through autosummary.
DATA_NAMES = ("ENV_ID", "SCENARIOS", "__version__")
#: The stages of the pipeline, in order: subpackage → section title.
STAGES = {
    "jobs": "Jobs: what the command line runs",
    "flight": "Flight files",
    "simulation": "Simulation",
    "compensation": "Compensation",
    "environment": "The tuning environment",
    "discovery": "Discovery",
    "errors": "Errors",
}
#: Modules of ``agents`` whose public classes and functions are part of the API.
AGENT_MODULES = (
    "agents.policies",
    "agents.policies.protocol",
    "agents.policies.baselines",
    "agents.policies.numpy_policy",
    "agents.evaluation.episodes",
    "agents.training.learners",
    "agents.training.hyperparameters",
)
PACKAGES = (aeromag_env, agents)


def public_api() -> dict[str, list[str]]:
    """Section title → names of ``aeromag_env.__all__`` in it (data names left out)."""
    sections: dict[str, list[str]] = {title: [] for title in STAGES.values()}
    for name in sorted(aeromag_env.__all__, key=str.lower):
        if name in DATA_NAMES:
            continue
        module = aeromag_env._PUBLIC[name]
        stage = module.split(".")[1]
        sections[STAGES[stage]].append(name)
    return {title: names for title, names in sections.items() if names}


def agents_public() -> dict[str, list[str]]:
    """Module → its public names that belong to it (defined there; constants in ``agents``)."""
    out: dict[str, list[str]] = {}
    for modname in AGENT_MODULES:
        module = importlib.import_module(modname)
        names = []
        for name, value in vars(module).items():
            if name.startswith("_") or inspect.ismodule(value):
                continue
            defined_here = getattr(value, "__module__", None) == modname
            constant = modname == "agents.policies" and name.isupper()
            if (defined_here and (inspect.isclass(value) or inspect.isfunction(value))) or (
                constant
            ):
                names.append(name)
        out[modname] = names
    return out


def modules(package: ModuleType) -> list[str]:
    """Every module of ``package`` (itself included), in name order."""
    names = [package.__name__]
    for info in pkgutil.walk_packages(package.__path__, package.__name__ + "."):
        names.append(info.name)
    return sorted(names)


def module_groups() -> dict[str, list[str]]:
    """Page name → its modules: one page per subpackage, one for each package's top modules."""
    groups: dict[str, list[str]] = {}
    for package in PACKAGES:
        for name in modules(package):
            parts = name.split(".")
            is_package = hasattr(importlib.import_module(name), "__path__")
            if len(parts) == 1 or (len(parts) == 2 and not is_package):
                key = parts[0]
            else:
                key = ".".join(parts[:2])
            groups.setdefault(key, []).append(name)
    return groups


def _data_entry(name: str) -> str:
    value: Any = getattr(aeromag_env, name)
    doc = {
        "ENV_ID": "The generic Gymnasium id (the scenario a keyword); see "
        ":doc:`../environments/index`.",
        "SCENARIOS": "The scenarios that are evaluated and tabled, each with its own id "
        "(:doc:`../environments/index`).",
        "__version__": "The package's version.",
    }[name]
    return f".. py:data:: {name}\n   :value: {value!r}\n\n   {doc}\n\n"


def api_page() -> str:
    parts = [
        ".. _api:\n\n",
        heading("Python API", "="),
        "\n",
        ".. module:: aeromag_env\n   :no-index:\n\n",
        ".. currentmodule:: aeromag_env\n\n",
        "Every name of ``aeromag_env.__all__`` (``import aeromag_env as am``; each is imported "
        "on first use), then the tuning policies of ``agents``. Generated from the docstrings "
        "when the documentation is built.\n\n",
        heading("Constants", "-"),
        "\n",
        *(_data_entry(n) for n in DATA_NAMES),
    ]
    for title, names in public_api().items():
        parts += [heading(title, "-"), "\n", _autosummary(names), "\n"]
    parts += [
        heading("Tuning policies (agents)", "-"),
        "\n",
        "The policies for the environment, all with stable-baselines3's ``predict`` shape, "
        "and the one evaluation path (``aeromag evaluate`` calls it). Import them from "
        "``agents`` (installed with the package).\n\n",
    ]
    for modname, names in agents_public().items():
        module = importlib.import_module(modname)
        constants = [n for n in names if n.isupper()]
        objects = [n for n in names if not n.isupper()]
        parts += [heading(literal(modname), "~"), "\n", f".. currentmodule:: {modname}\n\n"]
        for name in constants:
            value = getattr(module, name)
            shown = _shown_constant(value)
            parts.append(f".. autodata:: {name}\n   :no-value:\n\n   Value: ``{shown}``\n\n")
        parts += [_autosummary(objects), "\n"]
    parts.append(".. currentmodule:: aeromag_env\n\n")
    parts += [
        heading("Modules", "-"),
        "\n",
        "Every module, with its docstring (what it does, its conventions and references):\n\n",
        ".. toctree::\n   :maxdepth: 1\n\n",
        *(f"   modules/{group}\n" for group in module_groups()),
        "\n",
    ]
    return "".join(parts)


def _shown_constant(value: Any) -> str:
    """A constant's value for its entry; paths inside the package relative to it."""
    if isinstance(value, Path):
        return f"<package>/{value.parent.name}/{value.name}"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{k!r}: {_shown_constant(v)}" for k, v in value.items()) + "}"
    return repr(value)


def _autosummary(names: list[str]) -> str:
    body = "\n".join(f"   {n}" for n in names)
    return f".. autosummary::\n   :toctree: generated\n   :nosignatures:\n\n{body}\n"


def module_page(group: str, names: list[str]) -> str:
    parts = [heading(literal(group), "="), "\n"]
    for name in names:
        module = importlib.import_module(name)
        summary = (inspect.getdoc(module) or "").split("\n", 1)[0]
        parts += [
            heading(literal(name), "-") if name != group else "",
            "\n" if name != group else "",
            f".. automodule:: {name}\n   :no-members:\n\n",
        ]
        if not summary:
            parts.append(f"{text('(no module docstring)')}\n\n")
    return "".join(parts)


def write(out: Path) -> list[Path]:
    """Write the API page and the module pages; returns the paths."""
    pages = [out / "api.rst"]
    write_if_changed(pages[0], api_page())
    folder = out / "modules"
    for group, names in module_groups().items():
        path = folder / f"{group}.rst"
        write_if_changed(path, module_page(group, names))
        pages.append(path)
    remove_stale(folder, set(pages))
    return pages


__all__ = ["agents_public", "api_page", "module_groups", "public_api", "write"]
_ = indent  # shared helper kept importable for page code that needs it
