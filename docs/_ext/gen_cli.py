"""The command-line reference, written from the ``aeromag`` argument parser itself.

Every subcommand gets a section with its description, its usage line and one ``option``
directive per argument (help text, choices, default), so that each is a link target
(``:option:`aeromag compensate --method```) and ``aeromag --help`` and this page say the same.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from rst import heading, indent, literal, text, write_if_changed

from aeromag_env.cli.parser import build_parser

PROGRAM = "aeromag"


def subcommands(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    """Subcommand name → its parser, in ``--help`` order."""
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            return dict(action.choices)
    return {}


def short_help(parser: argparse.ArgumentParser) -> dict[str, str]:
    """Subcommand name → its one-line help."""
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            return {a.dest: a.help or "" for a in action._choices_actions}
    return {}


def documented_arguments(parser: argparse.ArgumentParser) -> list[argparse.Action]:
    """The arguments ``--help`` shows (suppressed ones and the subcommand slot left out)."""
    return [
        a
        for a in parser._actions
        if a.help != argparse.SUPPRESS and not isinstance(a, argparse._SubParsersAction)
    ]


def option_signature(parser: argparse.ArgumentParser, action: argparse.Action) -> str:
    """``-h, --help`` / ``--method {kf,fakf}`` / ``file``: the directive's argument."""
    formatter = parser._get_formatter()
    if not action.option_strings:
        return action.metavar if isinstance(action.metavar, str) else action.dest
    args = "" if action.nargs == 0 else " " + formatter._format_args(action, action.dest.upper())
    return ", ".join(f"{s}{args}" for s in action.option_strings)


def _option_body(parser: argparse.ArgumentParser, action: argparse.Action) -> str:
    formatter = parser._get_formatter()
    help_text = formatter._expand_help(action) if action.help else ""
    lines = [text(help_text) or "(no help text)"]
    facts = []
    if action.choices is not None and not isinstance(action.choices, range):
        facts.append("choices: " + ", ".join(literal(c) for c in action.choices))
    if action.required and action.option_strings:
        facts.append("required")
    if action.option_strings and action.default not in (None, False, argparse.SUPPRESS):
        facts.append("default: " + literal(action.default))
    if facts:
        lines.append("\n" + "; ".join(facts) + ".")
    return "\n".join(lines)


def command_section(name: str, parser: argparse.ArgumentParser, summary: str) -> str:
    program = f"{PROGRAM} {name}"
    usage = " ".join(parser.format_usage().split())
    group = [
        f".. _cli-{name}:\n\n",
        heading(f"``{program}``", "-"),
        "\n",
        f"*{text(summary)}*\n\n" if summary else "",
        text(parser.description or "") + "\n\n",
        "::\n\n" + indent(usage.replace("usage: ", "", 1)) + "\n\n",
        f".. program:: {program}\n\n",
    ]
    for action in documented_arguments(parser):
        group.append(f".. option:: {option_signature(parser, action)}\n\n")
        group.append(indent(_option_body(parser, action)) + "\n\n")
    return "".join(group)


def cli_page() -> str:
    parser = build_parser()
    commands = subcommands(parser)
    summaries = short_help(parser)
    rows = "\n".join(
        f"* :ref:`{PROGRAM} {n} <cli-{n}>` — {text(summaries.get(n, ''))}" for n in commands
    )
    top = [
        ".. _cli:\n\n",
        heading("Command line", "="),
        "\n",
        f"``{PROGRAM}`` is installed with the package (also "
        "``python -m aeromag_env.cli.main``). This "
        "page is generated from its argument parser (:func:`aeromag_env.cli.parser.build_parser`) "
        "when the documentation is built, so it lists every command and every option that "
        f"``{PROGRAM} COMMAND --help`` shows.\n\n",
        text(parser.description or "") + "\n\n",
        rows + "\n\n",
        text(parser.epilog or "") + ".\n\n",
        f".. program:: {PROGRAM}\n\n",
    ]
    for action in documented_arguments(parser):
        top.append(f".. option:: {option_signature(parser, action)}\n\n")
        top.append(indent(_option_body(parser, action)) + "\n\n")
    sections = [command_section(n, p, summaries.get(n, "")) for n, p in commands.items()]
    return "".join(top) + "".join(sections)


def write(out: Path) -> Path:
    path = out / "cli.rst"
    write_if_changed(path, cli_page())
    return path
