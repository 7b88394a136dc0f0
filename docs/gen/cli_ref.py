"""The command-line reference page (cli.md), written when the site is built (hooks.py) from the
parser the `fencesweep` command itself uses, fencesweep.cli.build_parser: every command, its usage,
description and arguments with their defaults, as `fencesweep COMMAND -h` prints them."""
from __future__ import annotations

import argparse
import functools
import html

#: the usage lines' width, whatever the terminal that builds the site
WIDTH = 100


def _subcommands(parser: argparse.ArgumentParser) -> list:
    """(name, one-line help, parser) of each command, in the order `fencesweep -h` lists them."""
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            helps = {a.dest: a.help for a in action._choices_actions}
            return [(name, helps.get(name) or "", sub) for name, sub in action.choices.items()]
    return []


def _text(text: str) -> str:
    """Help text for a Markdown table cell."""
    return html.escape(" ".join(str(text).split()), quote=False).replace("|", "\\|")


def _names(action: argparse.Action, parser: argparse.ArgumentParser) -> str:
    fmt = parser._get_formatter()
    if not action.option_strings:
        return f"`{fmt._metavar_formatter(action, action.dest)(1)[0]}`"
    if action.nargs == 0:
        return ", ".join(f"`{o}`" for o in action.option_strings)
    metavar = fmt._format_args(action, action.dest.upper())
    return ", ".join(f"`{o} {metavar}`" for o in action.option_strings)


def _default(action: argparse.Action) -> str:
    d = action.default
    if action.nargs == 0 or d is None or d == argparse.SUPPRESS or d == []:
        return ""
    if isinstance(d, list):
        return " ".join(f"`{v}`" for v in d)
    return f"`{d}`"


def argument_rows(parser: argparse.ArgumentParser) -> list:
    """The Markdown table of a parser's arguments: names, default, help (its %-expansions done)."""
    fmt = parser._get_formatter()
    rows = ["| argument | default | meaning |", "|---|---|---|"]
    for action in parser._actions:
        if action.help == argparse.SUPPRESS or isinstance(action, argparse._SubParsersAction):
            continue
        meaning = fmt._expand_help(action) if action.help else ""
        rows.append(f"| {_names(action, parser)} | {_default(action)} | {_text(meaning)} |")
    return rows


def usage(parser: argparse.ArgumentParser) -> str:
    """The usage lines without their "usage: " (the lines after the first moved left as far)."""
    first, *rest = parser.format_usage().rstrip().splitlines()
    cut = len("usage: ")
    return "\n".join([first[cut:]] + [line[cut:] if line[:cut].isspace() else line for line in rest])


def command_lines(name: str, summary: str, parser: argparse.ArgumentParser) -> list:
    parser.formatter_class = functools.partial(argparse.HelpFormatter, width=WIDTH)
    out = [f"## `fencesweep {name}`", "", _text(summary), ""]
    if parser.description:
        out += [_text(parser.description), ""]
    out += ["```text", usage(parser), "```", ""]
    return out + argument_rows(parser) + [""]


def page() -> str:
    from fencesweep.cli import build_parser

    parser = build_parser()
    parser.formatter_class = functools.partial(argparse.HelpFormatter, width=WIDTH)
    lines = ["# Command line", "",
             "Generated from the parser of the `fencesweep` command (`fencesweep.cli.build_parser`) when this site "
             "is built; `fencesweep COMMAND -h` prints the same. Bad input prints one message naming the value "
             "and what is allowed and exits with code 2; a file that cannot be written exits with code 1.", "",
             "```text", usage(parser), "```", ""]
    lines += argument_rows(parser) + [""]
    for name, summary, sub in _subcommands(parser):
        lines += command_lines(name, summary, sub)
    return "\n".join(lines)
