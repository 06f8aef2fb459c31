"""`scenescore completion bash|zsh`: scripts generated from the parser that complete every command,
its options and the fixed values of an option."""

from __future__ import annotations

import argparse
import shutil
import subprocess

import pytest

from scenescore.cli import build_parser, main


def _subparsers() -> dict[str, argparse.ArgumentParser]:
    p = build_parser()
    sub = next(a for a in p._actions if isinstance(a, argparse._SubParsersAction))
    return dict(sub.choices)


def _script(shell: str, capsys) -> str:
    assert main(["completion", shell]) == 0
    return capsys.readouterr().out


def test_bash_script_names_every_command_and_option(capsys):
    script = _script("bash", capsys)
    for name, parser in _subparsers().items():
        line = next((ln for ln in script.splitlines() if ln.strip().startswith(f"{name}) opts=")), None)
        assert line is not None, f"no completion for {name}"
        for action in parser._actions:
            for opt in action.option_strings:
                assert f" {opt}" in line or f'"{opt}' in line, f"{name} {opt}"


def _complete(script: str, words: list[str]) -> list[str]:
    """What the bash function offers for ``words`` (the last one being completed)."""
    call = " ".join(f"'{w}'" for w in words)
    code = (
        script
        + f"""
COMP_WORDS=({call}); COMP_CWORD=$((${{#COMP_WORDS[@]}} - 1)); COMPREPLY=()
_scenescore
printf '%s\\n' "${{COMPREPLY[@]}}"
"""
    )
    out = subprocess.run(["bash", "-c", code], capture_output=True, text=True, check=True).stdout
    return [w for w in out.splitlines() if w]


@pytest.mark.skipif(shutil.which("bash") is None, reason="no bash")
def test_bash_completes_commands_options_and_values(capsys):
    script = _script("bash", capsys)
    assert sorted(_complete(script, ["scenescore", "ex"])) == ["experiment", "explain", "export"]
    assert "missing" in _complete(script, ["scenescore", "experiment", ""])
    assert sorted(_complete(script, ["scenescore", "experiment", "--see"])) == ["--seed", "--seeds"]
    assert sorted(_complete(script, ["scenescore", "train", "d.jsonl", "--activation", ""])) == [
        "leaky_relu",
        "silu",
        "softplus",
    ]
    assert _complete(script, ["scenescore", "completion", ""]) == ["bash", "zsh"]
    assert _complete(script, ["scenescore", "train", "--out", ""]) == []  # a file: the shell's own


@pytest.mark.skipif(shutil.which("zsh") is None, reason="no zsh")
def test_zsh_script_parses_and_registers(capsys, tmp_path):
    script = _script("zsh", capsys)
    for name in _subparsers():
        assert f"\n            {name})\n" in script and f"'{name}:" in script
    f = tmp_path / "_scenescore"
    f.write_text(script)
    subprocess.run(["zsh", "-n", str(f)], check=True)
    code = f"autoload -Uz compinit && compinit -u -D; source {f}; print -r -- $_comps[scenescore]"
    done = subprocess.run(["zsh", "-f", "-c", code], capture_output=True, text=True, check=True)
    assert done.stdout.strip() == "_scenescore"


def test_an_unknown_shell_is_refused(capsys):
    with pytest.raises(SystemExit) as e:
        main(["completion", "fish"])
    assert e.value.code == 2 and "invalid choice: 'fish'" in capsys.readouterr().err
