"""Helpers of the hostile-input suite: a tiny untrained checkpoint, a valid scene, and the two outcomes
every case asserts (a library error naming what is wrong, or a one-line command-line error)."""

from __future__ import annotations

import json
import re
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from scenescore.cli import main

SCENE: dict[str, Any] = {
    "objects": [
        {"name": "plate", "category": "plate", "size": [0.2, 0.2], "pose": [0.0, 0.0, 0.0], "shape": "disk"},
        {"name": "fork", "category": "fork", "size": [0.19, 0.025], "pose": [-0.2, 0.0, 1.5]},
        {"name": "cup", "category": "cup", "size": [0.08, 0.08], "pose": None, "shape": "disk"},
    ],
    "bounds": [[-0.6, -0.6], [0.6, 0.6]],
}


def scene(**changes: Any) -> dict[str, Any]:
    """A deep copy of :data:`SCENE` with top-level keys changed."""
    d = json.loads(json.dumps(SCENE))
    d.update(changes)
    return d


def with_object(i: int, **changes: Any) -> dict[str, Any]:
    """:data:`SCENE` with object ``i``'s fields changed (``None`` values kept; ``...`` deletes the key)."""
    d = scene()
    for k, v in changes.items():
        if v is ...:
            d["objects"][i].pop(k, None)
        else:
            d["objects"][i][k] = v
    return d


def expect(fn: Callable[[], Any], error: type[BaseException], *names: str) -> str:
    """``fn()`` raises ``error`` (exactly that class or a subclass), with a one-line message naming every
    one of ``names``; returns the message."""
    with pytest.raises(error) as info:
        fn()
    msg = str(info.value)
    assert "\n" not in msg.strip(), f"message has several lines: {msg!r}"
    for n in names:
        assert n in msg, f"{n!r} not named in: {msg}"
    return msg


def run_cli(capsys: pytest.CaptureFixture, *argv: Any) -> tuple[int, str, str]:
    """``scenescore ARGV`` in this process: ``(exit code, stdout, stderr)``."""
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def cli_error(capsys: pytest.CaptureFixture, *argv: Any, names: tuple[str, ...] = ()) -> str:
    """The command exits 2 with exactly one line ``scenescore CMD: error: ...`` on stderr (naming every
    one of ``names``) and no traceback; returns that line."""
    try:
        code = main([str(a) for a in argv])
    except SystemExit as e:  # argparse's own errors: usage + one error line, exit 2
        code = e.code  # type: ignore[assignment]
    out, err = capsys.readouterr()
    assert code == 2, f"exit {code}; stderr: {err}"
    assert "Traceback" not in err
    lines = [ln for ln in err.strip().splitlines() if not ln.startswith(("usage:", " "))]
    assert len(lines) == 1, f"expected one error line, got: {err!r}"
    line = lines[0]
    assert re.match(rf"scenescore {re.escape(str(argv[0]))}: error: \S", line), line
    for n in names:
        assert n in line, f"{n!r} not named in: {line}"
    return line


def write(path: Path, data: Any) -> Path:
    """Write ``data``: bytes as they are, str as UTF-8, anything else as JSON."""
    path.parent.mkdir(parents=True, exist_ok=True)
    if isinstance(data, bytes):
        path.write_bytes(data)
    elif isinstance(data, str):
        path.write_text(data)
    else:
        path.write_text(json.dumps(data))
    return path
