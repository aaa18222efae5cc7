"""The site's sections and the root table of contents, from the files that exist.

The prose sections (getting started, how-to guides, background, results, lab notebook) are
written by hand; their file names are not known here. A section is a folder: its ``index.md``
when it has one (a hidden table of contents of the folder's other pages is added to it when
read), else a page generated in ``docs/_sections/`` that lists the folder's pages. The root
page's ``{sections}`` marker becomes the table of contents of the sections that exist.
"""

from __future__ import annotations

from pathlib import Path

from rst import remove_stale, write_if_changed

#: The site's navigation, in order: (title, a page or a folder, relative to docs/).
SECTIONS = (
    ("Getting started", "getting-started.md"),
    ("How-to guides", "howto"),
    ("Environments", "environments"),
    ("Reference", "reference"),
    ("Examples", "auto_examples"),
    ("Background", "background"),
    ("Results", "results"),
    ("Lab notebook", "lab-notebook"),
    ("Changelog", "changelog.md"),
)
MARKER = "{sections}"
GENERATED = "_sections"
_SUFFIXES = (".md", ".rst")


def _pages(folder: Path) -> list[Path]:
    return sorted(p for p in folder.iterdir() if p.suffix in _SUFFIXES and p.stem != "index")


def _has_index(folder: Path) -> bool:
    return any((folder / f"index{s}").exists() for s in _SUFFIXES)


def write_section_pages(docs: Path) -> list[str]:
    """Write the generated section pages; returns the root toctree's entries (docnames)."""
    entries: list[str] = []
    written: set[Path] = set()
    for title, where in SECTIONS:
        path = docs / where
        if where == "auto_examples":  # sphinx-gallery writes it later in the same event
            entries.append(f"{where}/index")
        elif path.is_file():
            entries.append(path.with_suffix("").name)
        elif path.is_dir() and _has_index(path):
            entries.append(f"{where}/index")
        elif path.is_dir() and _pages(path):
            page = docs / GENERATED / f"{where}.md"
            listing = "\n".join(f"../{where}/{p.stem}" for p in _pages(path))
            write_if_changed(page, f"# {title}\n\n```{{toctree}}\n:maxdepth: 1\n\n{listing}\n```\n")
            written.add(page)
            entries.append(f"{GENERATED}/{where}")
    if (docs / GENERATED).exists():
        remove_stale(docs / GENERATED, written, "*.md")
    return entries


def root_toctree(entries: list[str]) -> str:
    body = "\n".join(entries)
    return f"```{{toctree}}\n:hidden:\n:maxdepth: 2\n\n{body}\n```\n"


def folder_toctree(docname: str, docs: Path) -> str | None:
    """The hidden table of contents added to a hand-written section index (None: not one)."""
    folder, _, name = docname.rpartition("/")
    if name != "index" or folder not in {w for _, w in SECTIONS} or "/" in folder:
        return None
    if folder in ("environments", "reference", "auto_examples"):
        return None  # these index pages carry their own
    pages = _pages(docs / folder)
    index = [docs / folder / f"index{s}" for s in _SUFFIXES]
    if not pages or any(p.exists() and "toctree" in p.read_text() for p in index):
        return None
    listing = "\n".join(p.stem for p in pages)
    return f"\n\n```{{toctree}}\n:hidden:\n:maxdepth: 1\n\n{listing}\n```\n"
