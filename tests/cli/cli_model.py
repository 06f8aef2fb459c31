"""A small model trained through the command line, for the CLI tests (a helper module, not a test file)."""

from __future__ import annotations

from pathlib import Path

from scenescore.cli import main


def train_tiny(d: Path, iterations: int, *settings: str) -> None:
    """Six dining scenes in ``d/data.jsonl`` and a one-network model of them in ``d/m.ckpt``, trained
    for ``iterations`` with ``settings`` (more ``train`` options) and no cross-validation (``--val 0``):
    a model for the commands under test, whose held-out figures none of them reads."""
    assert main(["generate", "dining", "--n", "6", "--out", str(d / "data.jsonl"), "--seed", "1"]) == 0
    argv = ["train", "--members", "1", str(d / "data.jsonl"), "--out", str(d / "m.ckpt")]
    argv += ["--iterations", str(iterations), "--val", "0", "--quiet", "--force", *settings]
    assert main(argv) == 0
