"""MkDocs hook: the command-line reference, generated from the argparse definitions (and
docstrings' Sphinx roles shown as plain code on the API pages).

``docs/reference/cli/COMMAND.md`` (one page per top-level command) holds one marker per command,
``<!-- csm-cli COMMAND -->`` (``bench cones`` for a nested one, on ``bench.md``); at build time each marker becomes that command's usage, description
and a table of every argument with its help text, taken from :func:`csm_assets.cli.build_parser`,
so the page cannot drift from ``csm-assets COMMAND --help``. ``tests/test_docs.py`` calls
:func:`commands` and :func:`reference` directly, and checks the markers.
"""

from __future__ import annotations

import argparse
import re

MARKER = re.compile(r"<!-- csm-cli ([a-z ]+?) -->")
WIDTH = 80  # the usage line's wrap, fixed so the page does not depend on the terminal


def commands() -> dict[str, argparse.ArgumentParser]:
    """Every command's parser by name (``stepmap``, ``bench``, ``bench cones``, ...), in --help order."""
    from csm_assets.cli import build_parser

    found: dict[str, argparse.ArgumentParser] = {}

    def walk(parser: argparse.ArgumentParser, prefix: str) -> None:
        for action in parser._actions:  # argparse exposes its arguments only as _actions
            if isinstance(action, argparse._SubParsersAction):
                for name, sub in action.choices.items():
                    found[f"{prefix}{name}"] = sub
                    walk(sub, f"{prefix}{name} ")

    walk(build_parser(), "")
    return found


def _escape(text: str) -> str:
    """Help text as Markdown table-cell text: no markup, no HTML, no cell breaks."""
    text = " ".join(text.split())
    return re.sub(r"([\\`*_\[\]<>|#])", r"\\\1", text)


def _names(action: argparse.Action) -> str:
    if not action.option_strings:
        return f"`{action.metavar or action.dest}`"
    metavar = ""
    if action.nargs != 0:
        metavar = action.metavar or ("{" + ",".join(map(str, action.choices)) + "}" if action.choices
                                     else action.dest.upper())
        metavar = " " + (f"{metavar} [{metavar} ...]" if action.nargs in ("+", "*") else str(metavar))
    return ", ".join(f"`{s}{metavar}`" for s in action.option_strings)


def reference(name: str, parser: argparse.ArgumentParser) -> str:
    """Markdown for one command: usage, description, and its arguments by group."""
    parser.formatter_class = lambda prog: argparse.HelpFormatter(prog, width=WIDTH)
    formatter = parser._get_formatter()
    out = ["```text", parser.format_usage().strip(), "```", ""]
    if parser.description:
        out += [_escape(parser.description), ""]
    for group in parser._action_groups:
        rows = []
        for action in group._group_actions:
            if action.help == argparse.SUPPRESS or isinstance(action, argparse._HelpAction):
                continue
            if isinstance(action, argparse._SubParsersAction):
                for sub in action._choices_actions:
                    rows.append(f"| `{sub.dest}` | {_escape(sub.help or '')} |")
                continue
            rows.append(f"| {_names(action)} | {_escape(formatter._expand_help(action) if action.help else '')} |")
        if rows:
            out += [f"**{_escape(group.title)}**", "", "| argument | meaning |", "| --- | --- |", *rows, ""]
    return "\n".join(out)


def on_page_markdown(markdown: str, page, **kwargs) -> str:
    uri = page.file.src_uri
    if not uri.startswith("reference/cli/"):
        return markdown
    parsers = commands()

    def generate(match: re.Match) -> str:
        name = match.group(1)
        if name not in parsers or uri != f"reference/cli/{name.split()[0]}.md":
            raise ValueError(f"{uri}: no command {name!r} belongs here (commands: {', '.join(parsers)})")
        return reference(name, parsers[name])

    return MARKER.sub(generate, markdown)


ROLE = re.compile(r":(?:class|func|mod|data|meth|attr|exc|obj|const):<code>(~?)([^<]*)</code>")


def _plain_role(match: re.Match) -> str:
    short, name = match.groups()
    return f"<code>{name.rsplit('.', 1)[-1] if short else name}</code>"


def on_page_content(html: str, page, **kwargs) -> str:
    """Docstrings' Sphinx roles (``:func:`x```, ``:class:`~a.B```) shown as the code they name."""
    return ROLE.sub(_plain_role, html)
