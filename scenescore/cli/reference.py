"""The command-line reference: every ``scenescore`` command and nested subcommand, its usage, its
description and each option with its help, default and choices, rendered as Markdown from the parser
itself, so the page cannot drift from the command line.

``python -m scenescore.cli.reference --out docs/cli-reference.md`` writes the checked-in page;
``--check`` only says whether that file is current. The page reads the same on any machine and terminal:
usage lines are wrapped here at :data:`WIDTH` columns (not by argparse at the terminal's ``COLUMNS``),
and an option whose default depends on the machine (threads, memory) shows the fixed description set
with :func:`describe_default` instead of its value.
"""

from __future__ import annotations

import argparse
import inspect
import re
import sys
from pathlib import Path, PurePath

from .completion import subcommands

WIDTH = 88  # columns of a usage block on the page
COMMAND = "python -m scenescore.cli.reference --out docs/cli-reference.md"  # regenerates the page
_DEFAULT_TEXT = "default_text"  # the attribute describe_default sets on an action

# characters that Markdown (Python-Markdown and GitHub's) would read as markup in help text
_ESCAPED = re.compile(r"([\\`*_\[\]|])")


def describe_default(action: argparse.Action, text: str) -> argparse.Action:
    """Show ``text`` on the reference page as ``action``'s default, in place of its value: for a
    default that depends on the machine (a core count, a memory size), which would otherwise make the
    page differ from one machine to the next. Returns ``action``."""
    setattr(action, _DEFAULT_TEXT, text)
    return action


def _formatter(parser: argparse.ArgumentParser) -> argparse.HelpFormatter:
    """``parser``'s own help formatter with a fixed, wide width (no wrapping by the terminal's
    ``COLUMNS``) and, on Pythons whose argparse colours help, no colour."""
    cls = parser.formatter_class
    extra = {"color": False} if "color" in inspect.signature(cls).parameters else {}
    return cls(prog=parser.prog, width=100_000, **extra)  # type: ignore[call-arg]


def _text(text: str) -> str:
    """Help text as one line of Markdown prose: whitespace collapsed, markup characters escaped."""
    text = _ESCAPED.sub(r"\\\1", " ".join(text.split()))
    return text.replace("<", "&lt;")


def _tokens(usage: str) -> list[str]:
    """A one-line usage split at the spaces outside brackets, so that wrapping keeps ``[--out OUT]``,
    ``{a,b}``, ``[--a | --b]`` and ``COMMAND ...`` whole."""
    out: list[str] = []
    depth, start = 0, 0
    for i, ch in enumerate(usage + " "):
        depth += ch in "[({"
        depth -= ch in "])}"
        if ch == " " and depth == 0:
            word = usage[start:i]
            if word == "..." and out:
                out[-1] += " ..."
            elif word:
                out.append(word)
            start = i + 1
    return out


def usage(parser: argparse.ArgumentParser) -> str:
    """``parser``'s usage, wrapped at :data:`WIDTH` with continuation lines indented under the first
    argument (argparse's own layout, whatever the terminal)."""
    f = _formatter(parser)
    f.add_usage(parser.usage, parser._actions, parser._mutually_exclusive_groups, prefix="")
    line = " ".join(f.format_help().split())
    head = f"usage: {parser.prog}"
    rest = _tokens(line[len(parser.prog) :].strip() if line.startswith(parser.prog) else line)
    lines, indent = [head], " " * (len(head) + 1)
    for token in rest:
        if lines[-1] != head and len(lines[-1]) + 1 + len(token) > WIDTH:
            lines.append(indent + token)  # the head line always takes its first token
        else:
            lines[-1] += " " + token
    return "\n".join(lines)


def _invocation(f: argparse.HelpFormatter, action: argparse.Action) -> str:
    """``--out OUT``, ``-n, --n N`` or ``data``: how an argument is written, as the code of a cell."""
    if not action.option_strings:
        return f._format_args(action, f._get_default_metavar_for_positional(action))
    names = ", ".join(action.option_strings)
    if action.nargs == 0:
        return names
    return f"{names} {f._format_args(action, f._get_default_metavar_for_optional(action))}"


def _value(value: object) -> str:
    if isinstance(value, PurePath):
        return value.as_posix()  # the same on every platform
    if isinstance(value, (list, tuple)):
        return " ".join(_value(v) for v in value)
    return repr(value) if value == "" else str(value)


def _default(action: argparse.Action) -> str:
    """The default cell: the fixed description where one is set, else the value; empty where there is
    none to show (no default, a flag's off state, a help or version action)."""
    text = getattr(action, _DEFAULT_TEXT, None)
    if text is not None:
        return _text(text)
    value = action.default
    flag = isinstance(value, bool) and action.nargs == 0
    if value is None or value is argparse.SUPPRESS or flag or value == []:
        return ""
    return f"`{_value(value)}`"


def _help(f: argparse.HelpFormatter, action: argparse.Action) -> str:
    """The help cell: the help text as ``--help`` shows it (``%(default)s`` and the like filled in),
    then the choices where the set is fixed."""
    text = _text(f._expand_help(action)) if action.help else ""
    if action.choices is not None and not isinstance(action, argparse._SubParsersAction):
        listed = ", ".join(f"`{_value(c)}`" for c in action.choices)
        text = f"{text.rstrip('.')}. Choices: {listed}." if text else f"Choices: {listed}."
    return text


def _table(f: argparse.HelpFormatter, head: str, actions: list[argparse.Action]) -> list[str]:
    if not actions:
        return []
    rows = [f"| {head} | what it does | default |", "| --- | --- | --- |"]
    for a in actions:
        name = _invocation(f, a).replace("|", "\\|")
        rows.append(f"| `{name}` | {_help(f, a)} | {_default(a)} |")
    return [*rows, ""]


def _shown(parser: argparse.ArgumentParser) -> list[argparse.Action]:
    """The actions the page lists: not ``--help`` (every command has it), not hidden ones, not the
    subcommand choice (its commands get sections of their own)."""
    skip = (argparse._HelpAction, argparse._SubParsersAction)
    return [a for a in parser._actions if not isinstance(a, skip) and a.help is not argparse.SUPPRESS]


def anchor(path: list[str]) -> str:
    """The anchor of a command's heading (``scenescore-compare``), as MkDocs and GitHub both make it."""
    return "-".join(path)


def _section(parser: argparse.ArgumentParser, path: list[str], help_text: str) -> list[str]:
    """One command's section, then its subcommands' sections one level down (the program itself is the
    page's title: its commands are level-2 headings, theirs level 3)."""
    f = _formatter(parser)
    lines = [f"{'#' * min(len(path), 6)} `{' '.join(path)}`", ""] if len(path) > 1 else []
    about = parser.description or help_text
    if about:
        lines += [_text(about), ""]
    lines += ["```text", usage(parser), "```", ""]
    shown = _shown(parser)
    lines += _table(f, "argument", [a for a in shown if not a.option_strings])
    lines += _table(f, "option", [a for a in shown if a.option_strings])
    children = _children(parser)
    if children:
        lines += ["| command | what it does |", "| --- | --- |"]
        lines += [f"| [`{n}`](#{anchor([*path, n])}) | {_text(h)} |" for n, h, _ in children]
        lines.append("")
    for name, child_help, child in children:
        lines += _section(child, [*path, name], child_help)
    return lines


def _children(parser: argparse.ArgumentParser) -> list[tuple[str, str, argparse.ArgumentParser]]:
    """``parser``'s subcommands, each once (an alias names a parser already listed) and none hidden."""
    seen: set[int] = set()
    out = []
    for name, help_text, child in subcommands(parser):
        if id(child) in seen or help_text == argparse.SUPPRESS:
            continue
        seen.add(id(child))
        out.append((name, help_text, child))
    return out


def reference(parser: argparse.ArgumentParser | None = None) -> str:
    """The whole command-line reference page for ``parser`` (default: ``scenescore``'s own) as Markdown."""
    if parser is None:
        from . import build_parser

        parser = build_parser()
    intro = [
        "# Command-line reference",
        "",
        f"<!-- generated from the parser by `{COMMAND}`; do not edit by hand -->",
        "",
        f"Every command of `{parser.prog}` with its arguments and options, generated from the command line "
        "itself. Every command also takes `-h`/`--help`. [The command line](cli.md) describes what holds "
        "across commands (errors, devices, seeds, outputs, budgets).",
        "",
    ]
    return "\n".join(intro + _section(parser, [parser.prog], "")).rstrip("\n") + "\n"


def main(argv: list[str] | None = None) -> int:
    """``python -m scenescore.cli.reference``: print the page, write it (``--out``), or check it."""
    p = argparse.ArgumentParser(prog="python -m scenescore.cli.reference", description=main.__doc__)
    p.add_argument("--out", type=Path, help="write the page here instead of printing it")
    p.add_argument("--check", action="store_true", help="exit 1 if --out's file differs from the page")
    args = p.parse_args(argv)
    page = reference()
    if args.check:
        if args.out is None:
            p.error("--check needs --out FILE")
        current = args.out.read_text(encoding="utf-8") if args.out.exists() else ""
        if current != page:
            print(f"{args.out} is out of date; run: {COMMAND}", file=sys.stderr)
            return 1
        return 0
    if args.out is None:
        sys.stdout.write(page)
    else:
        args.out.write_text(page, encoding="utf-8", newline="\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
