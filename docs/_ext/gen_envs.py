"""One page per registered environment id, in Gymnasium's layout, written from the code.

The prose of each section comes from the environment class's docstring (its ``## Section``
headings) and the scenario's row of the table in :mod:`aeromag_env.environment.scenarios`; the
spaces, the observation and action tables and the arguments table come from ``gym.make(id)``
itself, through :mod:`env_adapter`, so a page cannot disagree with the code.
"""

from __future__ import annotations

import inspect
import re
from dataclasses import fields
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
from env_adapter import Entry, action_entries, all_observations_overrides, observation_entries
from gymnasium.envs.registration import registry
from numpydoc.docscrape import NumpyDocString
from rst import heading, list_table, literal, remove_stale, text, write_if_changed

import aeromag_env
from aeromag_env.environment import ids, scenarios
from aeromag_env.environment.env import AeroMagCompensationEnv, EnvConfig, env_config

#: The sections of a Gymnasium environment page, in order.
SECTIONS = (
    "Description",
    "Action Space",
    "Observation Space",
    "Rewards",
    "Starting State",
    "Episode End",
    "Arguments",
    "Version History",
)


def registered_ids() -> list[str]:
    """Every id in Gymnasium's registry whose entry point is this package's environment, in
    registration order (the generic one, then one per scenario)."""
    ours = f"{AeroMagCompensationEnv.__module__}:{AeroMagCompensationEnv.__name__}"
    return [i for i, spec in registry.items() if spec.entry_point == ours]


def _is_generic(env_id: str) -> bool:
    return "scenario" not in registry[env_id].kwargs


def page_name(env_id: str) -> str:
    """The page of ``env_id`` (no folder, no suffix): ``AeroMag/NoiseBursts-v0`` →
    ``noise-bursts``."""
    if _is_generic(env_id):
        return "generic"
    return str(registry[env_id].kwargs["scenario"]).replace("_", "-")


def write_all(out: Path) -> list[Path]:
    """Write the index and every id's page into ``out``; returns the paths written or kept."""
    pages = [out / "index.rst"]
    write_if_changed(pages[0], _index())
    for env_id in registered_ids():
        path = out / f"{page_name(env_id)}.rst"
        write_if_changed(path, env_page(env_id))
        pages.append(path)
    remove_stale(out, set(pages))
    return pages


def _role(scenario: str) -> str:
    if scenario in ids.TRAINING_SCENARIOS:
        return "training only (not evaluated; ``aeromag evaluate`` refuses it)"
    if scenario in ids.CONTROL_SCENARIOS:
        return "evaluated as the control (no headroom by design; not in the suite)"
    return "evaluated, in the suite"


def _index() -> str:
    rows = []
    for env_id in registered_ids():
        env = gym.make(env_id)
        scenario = env.unwrapped.config.scenario
        generic = _is_generic(env_id)
        rows.append(
            [
                f":doc:`{env_id} <{page_name(env_id)}>`",
                literal(scenario) + (" (default; ``scenario=`` keyword)" if generic else ""),
                "any scenario" if generic else text(_role(scenario)),
                literal(env.action_space),
                literal(env.observation_space),
            ]
        )
        env.close()
    toc = "\n".join(f"   {page_name(i)}" for i in registered_ids())
    return (
        heading("Environments", "=")
        + "\n"
        + "``import aeromag_env`` registers these Gymnasium ids. Each page is generated from the "
        "environment's own definitions when the documentation is built: the spaces and the "
        "tables come from ``gym.make(id)``.\n\n"
        + list_table(["id", "scenario", "role", "action space", "observation space"], rows)
        + "\n.. toctree::\n   :hidden:\n\n"
        + toc
        + "\n"
    )


def env_page(env_id: str) -> str:
    """The reStructuredText page of ``env_id``."""
    env = gym.make(env_id)
    config = env.unwrapped.config
    scenario = config.scenario
    generic = _is_generic(env_id)
    docs = docstring_sections(AeroMagCompensationEnv)
    make = f'gym.make("{env_id}")'
    summary = list_table(
        None,
        [
            ["Make", literal(make)],
            [
                "Vector form",
                literal(
                    f'gym.make_vec("{env_id}", num_envs=8, vectorization_mode="vector_entry_point")'
                ),
            ],
            [
                "Scenario",
                literal(scenario) + (" by default (``scenario=`` chooses)" if generic else ""),
            ],
            ["Role", "any scenario" if generic else text(_role(scenario))],
            ["Action space", literal(env.action_space)],
            ["Observation space", literal(env.observation_space)],
            ["Entry point", ":class:`aeromag_env.AeroMagCompensationEnv`"],
        ],
        "20 80",
    )
    parts = [
        f".. _env-{page_name(env_id)}:\n\n",
        heading(env_id, "=", overline=True),
        "\n",
        summary,
    ]
    body = {
        "Description": _description(scenario, generic) + docs["Description"],
        "Action Space": _action_section(env) + docs["Action Space"],
        "Observation Space": _observation_section(env_id, env) + docs["Observation Space"],
        "Rewards": docs["Rewards"],
        "Starting State": docs["Starting State"],
        "Episode End": docs["Episode End"],
        "Arguments": docs["Arguments"] + "\n" + _arguments_table(config),
        "Version History": docs["Version History"],
    }
    for name in SECTIONS:
        parts += ["\n", heading(name, "-"), "\n", body[name].strip() + "\n"]
    env.close()
    return "".join(parts)


def docstring_sections(cls: type) -> dict[str, str]:
    """The ``## Section`` parts of a class docstring, as reStructuredText (Markdown tables,
    which the generated tables replace, are left out)."""
    doc = inspect.cleandoc(cls.__doc__ or "")
    sections: dict[str, list[str]] = {name: [] for name in SECTIONS}
    current: list[str] | None = None
    for line in doc.splitlines():
        if line.startswith("## "):
            current = sections.setdefault(line[3:].strip(), [])
        elif current is not None and not line.lstrip().startswith("|"):
            current.append(line)
    return {name: "\n".join(lines).strip() + "\n" for name, lines in sections.items()}


def scenario_rows() -> dict[str, str]:
    """Each scenario's cell of the table in the scenarios module's docstring (reStructuredText)."""
    doc = inspect.cleandoc(scenarios.__doc__ or "")
    lines = doc.splitlines()
    rules = [i for i, line in enumerate(lines) if re.fullmatch(r"=+ +=+", line)]
    start = len(lines[rules[0]].split()[0]) + 1
    rows: dict[str, list[str]] = {}
    name = ""
    for line in lines[rules[1] + 1 : rules[2]]:
        key = line[:start].strip()
        if key:
            name = key.strip("`")
            rows[name] = []
        rows[name].append(line[start:].strip())
    return {key: " ".join(words) for key, words in rows.items()}


def _scenario_notes(scenario: str) -> list[str]:
    """The paragraphs after the scenarios table that name ``scenario`` or every episode."""
    doc = inspect.cleandoc(scenarios.__doc__ or "")
    after = doc.split("=" * 10)[-1].split("\n", 1)[-1]
    paragraphs = [" ".join(p.split()) for p in after.split("\n\n") if p.strip()]
    return [p for p in paragraphs if f"``{scenario}``" in p or p.startswith("Every episode")]


def _description(scenario: str, generic: bool) -> str:
    rows = scenario_rows()
    if generic:
        table = list_table(
            ["scenario", "what varies and what the tuner must do"],
            [[literal(s), rows[s]] for s in ids.SCENARIOS + ids.TRAINING_SCENARIOS],
            "25 75",
        )
        return _here(scenarios) + (
            "The generic id: the scenario is a keyword, "
            f'``gym.make("{ids.ENV_ID}", scenario="nonstationary")``, ``nominal`` by '
            "default; each scenario also has an id of its own (:doc:`index`).\n\n"
            + table
            + "\n"
            + _here(AeroMagCompensationEnv)
        )
    notes = "\n\n".join(_scenario_notes(scenario))
    return (
        f"{_here(scenarios)}**The scenario** ``{scenario}``: {rows[scenario]}\n\n{notes}\n\n"
        f"{_here(AeroMagCompensationEnv)}**The task.** "
    )


def _here(obj: Any) -> str:
    """Sets the module that relative references in the prose that follows are read in."""
    module = obj.__name__ if inspect.ismodule(obj) else obj.__module__
    return f".. currentmodule:: {module}\n\n"


def _entry_rows(entries: list[Entry], with_switch: bool) -> list[list[str]]:
    rows = []
    for i, e in enumerate(entries):
        row = [str(i), literal(e.name), f"[{e.low:g}, {e.high:g}]", _meaning(e.meaning)]
        if with_switch:
            row.append(literal(e.switch) if e.switch else "always")
        rows.append(row)
    return rows


def _meaning(meaning: str) -> str:
    """A meaning as written in the code: double-backquoted parts stay literals."""
    parts = re.split(r"(``[^`]+``)", meaning)
    return "".join(p if p.startswith("``") else text(p, collapse=False) for p in parts)


def _action_section(env: Any) -> str:
    entries = action_entries(env.unwrapped.config)
    split = action_entries(env_config(action={"permanent": "graded"}))
    table = list_table(
        ["index", "action", "range", "meaning"], _entry_rows(entries, False), "8 14 12 66"
    )
    note = (
        "\nWith a separate T_p action (``action={'permanent': 'graded'}``) the action has "
        f"{len(split)} entries: " + ", ".join(literal(e.name) for e in split) + ".\n\n"
    )
    return (
        f"``{env.action_space}``, one entry per row (``gym.make`` of this id):\n\n" + table + note
    )


def _observation_section(env_id: str, env: Any) -> str:
    config = env.unwrapped.config
    entries = observation_entries(config)
    overrides = all_observations_overrides()
    full_env = gym.make(env_id, **overrides)
    full = observation_entries(full_env.unwrapped.config)
    assert len(full) == full_env.observation_space.shape[0]
    full_env.close()
    settings = ", ".join(f"{k}={v}" for k, v in overrides.items())
    return (
        f"``{env.observation_space}`` with this id's defaults, one entry per row:\n\n"
        + list_table(
            ["index", "observation", "range", "meaning"], _entry_rows(entries, False), "8 22 12 58"
        )
        + "\nEvery observation the environment can give, in the order it gives them, and the "
        f'setting that adds each (all of them: ``gym.make("{env_id}", {settings})``):\n\n'
        + list_table(
            ["index", "observation", "range", "meaning", "added by"],
            _entry_rows(full, True),
            "7 22 10 46 15",
        )
        + "\n"
    )


def _arguments_table(config: EnvConfig) -> str:
    meanings = _attribute_meanings(EnvConfig)
    rows = [
        [literal(f.name), literal(repr(getattr(config, f.name))), meanings.get(f.name, "")]
        for f in fields(EnvConfig)
    ]
    return (
        "\nThe settings (:class:`aeromag_env.EnvConfig`; keywords of ``gym.make``) and their "
        "values under this id:\n\n"
        + list_table(["setting", "value here", "meaning"], rows, "20 15 65")
    )


def _attribute_meanings(cls: type) -> dict[str, str]:
    """Attribute name → its numpydoc entry (type and description joined) as reStructuredText."""
    out: dict[str, str] = {}
    for item in NumpyDocString(inspect.getdoc(cls) or "")["Attributes"]:
        meaning = " ".join([item.type, *item.desc]).strip()
        for name in item.name.split(","):
            out[name.strip()] = " ".join(meaning.split())
    return out


def observation_names_of(env_id: str, **kwargs: Any) -> tuple[list[str], np.ndarray, np.ndarray]:
    """Names and bounds the page of ``env_id`` shows (for the tests)."""
    env = gym.make(env_id, **kwargs)
    entries = observation_entries(env.unwrapped.config)
    env.close()
    return (
        [e.name for e in entries],
        np.array([e.low for e in entries]),
        np.array([e.high for e in entries]),
    )


assert aeromag_env.ENV_ID == ids.ENV_ID
