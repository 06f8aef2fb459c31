"""The Python snippets of docs/extending.md run as written."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

DOCS = Path(__file__).resolve().parents[1] / "docs"


def _python_blocks(path: Path) -> list[str]:
    return re.findall(r"```python\n(.*?)```", path.read_text(), flags=re.S)


@pytest.mark.parametrize("doc", ["extending.md"])
def test_python_snippets_run(doc, capsys):
    blocks = _python_blocks(DOCS / doc)
    assert blocks, f"{doc} has no python block"
    for code in blocks:
        exec(compile(code, f"{doc}:snippet", "exec"), {"__name__": "snippet"})
    assert "solver langevin>casadi" in capsys.readouterr().out
