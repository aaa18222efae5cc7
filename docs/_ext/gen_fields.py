"""The flight-file reference: formats, our field names and every alias, from the code's tables.

The prose is the docstrings of :mod:`aeromag_env.flight.files` (formats) and
:mod:`aeromag_env.flight.data` (the fields we use, with units); the lists are
:data:`aeromag_env.flight.aliases.SGL_2020_FIELDS`, ``EXTRA_FIELDS`` and ``ALIASES`` as they are.
"""

from __future__ import annotations

import inspect
from itertools import groupby
from pathlib import Path

from rst import heading, list_table, literal, text, write_if_changed

from aeromag_env.flight import aliases, data, files


def _module_prose(module: object) -> str:
    """A module docstring without its first line (the page has its own title)."""
    doc = inspect.cleandoc(getattr(module, "__doc__", "") or "")
    body = doc.split("\n", 1)[1].strip() + "\n" if "\n" in doc else ""
    return f".. currentmodule:: {getattr(module, '__name__', '')}\n\n{body}"


def fields_page() -> str:
    alias_sections = []
    for source, rows in groupby(aliases.ALIASES, key=lambda a: a.source):
        table = list_table(
            ["name in the file", "our name"],
            [[literal(a.original), literal(a.canonical)] for a in rows],
            "50 50",
        )
        alias_sections.append(heading(text(source), "~") + "\n" + table + "\n")
    sgl = ", ".join(literal(n) for n in aliases.SGL_2020_FIELDS)
    extra = ", ".join(literal(n) for n in aliases.EXTRA_FIELDS)
    return "".join(
        [
            ".. _flight-fields:\n\n",
            heading("Flight files: formats, fields and aliases", "="),
            "\n",
            "Generated from the package's own tables when the documentation is built "
            "(:mod:`aeromag_env.flight.files`, :mod:`aeromag_env.flight.data`, "
            ":mod:`aeromag_env.flight.aliases`).\n\n",
            heading("Formats", "-"),
            "\n",
            _module_prose(files),
            "\n",
            heading("The fields we use", "-"),
            "\n",
            _module_prose(data),
            "\n",
            heading("Every name we call our own", "-"),
            "\n",
            "The SGL 2020 data set's field names (SGL 2021 uses a subset): ",
            sgl,
            ".\n\nOur names beyond SGL's: ",
            extra,
            "; and the numbered or lettered families ``mag_<n>_uc``/``_c``/``_lag``/``_dc``/"
            "``_igrf``, ``flux_<s>_x``/``_y``/``_z``/``_t``, ``cur_*``, ``vol_*``, ``temp_*`` "
            "and ``truth_*``.\n\n",
            heading("Aliases", "-"),
            "\n",
            _module_prose(aliases),
            "\n",
            f"Every row of :data:`aeromag_env.flight.aliases.ALIASES` "
            f"({len(aliases.ALIASES)} rows), by source. Matching ignores case, and any case "
            "variant of one of our names (``TT``, ``LAT``, ``DIURNAL``…) is read as that "
            "name.\n\n",
            *alias_sections,
        ]
    )


def write(out: Path) -> Path:
    path = out / "flight-fields.rst"
    write_if_changed(path, fields_page())
    return path
