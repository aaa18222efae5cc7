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


DOCS = GUIDE.parents[1]


def first_column(page: Path, heading: str) -> set[str]:
    """The code names in the first column of the first table under ``heading`` on ``page``."""
    section = page.read_text().split(heading, 1)[1]
    names: set[str] = set()
    started = False
    for line in section.splitlines():
        if line.startswith("|"):
            started = True
            names |= set(re.findall(r"`([^`]+)`", line.strip("|").split("|")[0]))
        elif started:
            break
    return names


def test_the_scenario_table_lists_every_scenario() -> None:
    from aeromag_env import SCENARIOS

    page = DOCS / "background" / "benchmark-methodology.md"
    assert first_column(page, "## Scenarios") == set(SCENARIOS)


def test_the_guide_lists_every_registered_id() -> None:
    import gymnasium as gym

    import aeromag_env  # noqa: F401  (registers the ids)

    text = (DOCS / "howto" / "train-and-evaluate.md").read_text()
    listed = set(re.findall(r"`(AeroMag[\w/]*-v\d+)`", text))
    registered = {k for k in gym.registry if k.startswith("AeroMag")}
    assert registered <= listed, f"not in the guide: {sorted(registered - listed)}"
    assert listed <= registered, f"not registered: {sorted(listed - registered)}"


def test_the_effects_table_names_every_effect_of_the_library() -> None:
    from aeromag_env.simulation.effects import EFFECTS

    page = DOCS / "background" / "discovery.md"
    assert first_column(page, "## The effects library") == set(EFFECTS)
