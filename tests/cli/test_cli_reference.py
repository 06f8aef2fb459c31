"""docs/cli-reference.md is generated from the parser: the checked-in page is the one the parser renders
now, it lists every command and option, and it reads the same on any terminal and machine."""

from __future__ import annotations

import argparse
import os
from pathlib import Path

import pytest

from scenescore.cli import build_parser
from scenescore.cli.completion import subcommands
from scenescore.cli.reference import COMMAND, WIDTH, describe_default, main, reference

PAGE = Path(__file__).resolve().parents[2] / "docs" / "cli-reference.md"


@pytest.fixture(scope="module")
def page() -> str:
    return reference()


def test_the_checked_in_page_is_current(page):
    current = PAGE.read_text(encoding="utf-8") if PAGE.exists() else ""
    assert current == page, f"docs/cli-reference.md differs from the parser; regenerate it: {COMMAND}"


def _walk(
    parser: argparse.ArgumentParser, path: list[str]
) -> list[tuple[list[str], argparse.ArgumentParser]]:
    out = [(path, parser)]
    for name, _, child in subcommands(parser):
        out += _walk(child, [*path, name])
    return out


def test_every_command_and_option_is_on_the_page(page):
    commands = _walk(build_parser(), ["scenescore"])
    assert len(commands) > 10
    for path, parser in commands[1:]:
        heading = f"{'#' * len(path)} `{' '.join(path)}`\n"
        assert heading in page, f"no section for {' '.join(path)}"
        section = page.split(heading, 1)[1].split("\n## ", 1)[0]
        for action in parser._actions:
            for opt in action.option_strings:
                if opt not in ("-h", "--help"):
                    assert f"`{opt}" in section or f", {opt}" in section, f"{' '.join(path)} {opt}"


def test_the_page_is_the_same_on_any_terminal_and_machine(page, monkeypatch):
    monkeypatch.setenv("COLUMNS", "37")
    monkeypatch.setenv("SCENESCORE_MEMORY_GB", "3.5")
    monkeypatch.setattr(os, "cpu_count", lambda: 97)
    assert reference() == page
    monkeypatch.setenv("COLUMNS", "400")
    assert reference() == page
    blocks = page.split("```text\n")[1:]
    for block in blocks:
        for line in block.split("```", 1)[0].splitlines():
            assert len(line) <= WIDTH, line


def _toy() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="toy", description="A toy | with <markup> *and* _under_ scores.")
    sub = p.add_subparsers(dest="cmd", metavar="COMMAND")
    outer = sub.add_parser("outer", help="the outer command", description="Outer's description.")
    outer.add_argument("--out", type=Path, default=Path("runs") / "x", help="where it goes")
    describe_default(
        outer.add_argument("--jobs", type=int, default=os.cpu_count(), help="workers"), "one per core"
    )
    outer.add_argument("--mode", choices=["fast", "slow"], default="fast", help="how")
    outer.add_argument("--hidden", help=argparse.SUPPRESS)
    outer.add_argument("--flag", action="store_true", help="a switch (default %(default)s)")
    inner = outer.add_subparsers(dest="sub").add_parser("inner", help="the inner one")
    inner.add_argument("things", nargs="+", help="what to do it to")
    for i in range(12):
        inner.add_argument(f"--long-option-{i}", metavar="VALUE", help=f"option {i}")
    return p


def test_a_toy_parser_renders_nested_commands_defaults_and_choices():
    text = reference(_toy())
    assert "## `toy outer`\n\nOuter's description." in text
    assert "### `toy outer inner`\n\nthe inner one" in text
    assert "[`outer`](#toy-outer)" in text and "[`inner`](#toy-outer-inner)" in text
    assert "| `--out OUT` | where it goes | `runs/x` |" in text
    assert "| `--jobs JOBS` | workers | one per core |" in text and f"`{os.cpu_count()}`" not in text
    assert "Choices: `fast`, `slow`. | `fast` |" in text
    assert "--hidden" not in text and "`-h, --help`" not in text
    assert "a switch (default False) |  |" in text  # a flag's off state is not a default worth a cell
    assert "A toy \\| with &lt;markup> \\*and\\* \\_under\\_ scores." in text
    assert "| `things [things ...]` | what to do it to |  |" in text
    usage = text.split("### `toy outer inner`", 1)[1].split("```text\n", 1)[1].split("```", 1)[0]
    lines = usage.splitlines()
    assert len(lines) > 2 and all(len(ln) <= WIDTH for ln in lines)
    assert lines[0].startswith("usage: toy outer inner [-h]")
    assert all(ln.startswith(" " * len("usage: toy outer inner ")) for ln in lines[1:])


def test_check_says_when_the_file_is_stale_and_write_makes_it_current(tmp_path, capsys):
    out = tmp_path / "ref.md"
    out.write_text("old\n")
    assert main(["--out", str(out), "--check"]) == 1
    assert COMMAND in capsys.readouterr().err
    assert main(["--out", str(out)]) == 0
    assert main(["--out", str(out), "--check"]) == 0
    assert out.read_text().startswith("# Command-line reference\n")
