"""Tables the guides write out by hand agree with the code they describe.

The alias table of ``docs/howto/own-flight-files.md`` groups the renamings of
:func:`aeromag_env.flight.aliases.alias_table_markdown` by source; every pair it shows must be one
the reader applies, and every renaming the reader applies must be shown.
"""

from __future__ import annotations

import re
from pathlib import Path

from aeromag_env.flight.aliases import alias_table_markdown

GUIDE = Path(__file__).resolve().parents[1] / "docs" / "howto" / "own-flight-files.md"


def pairs_in(table: str) -> set[tuple[str, str]]:
    """The (name in the file, our name) pairs of the Markdown table rows in ``table``."""
    out = set()
    for line in table.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) < 2 or not cells[0].startswith("`"):
            continue
        theirs = re.findall(r"`([^`]+)`", cells[0])
        ours = re.findall(r"`([^`]+)`", cells[1])
        if len(theirs) == len(ours):
            out |= set(zip(theirs, ours, strict=True))
    return out


def test_the_guides_alias_table_is_the_readers() -> None:
    section = GUIDE.read_text().split("## Other names for the same fields")[1].split("\n## ")[0]
    shown = pairs_in(section)
    applied = pairs_in(alias_table_markdown())
    assert shown, "the guide's alias table was not found"
    assert shown - applied == set(), "the guide shows renamings the reader does not apply"
    assert applied - shown == set(), "the reader applies renamings the guide does not show"
