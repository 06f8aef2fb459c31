"""TensorBoard logs of training (the optional ``tensorboard`` extra): every iteration's loss and learning
rate, then an evaluation's figures."""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from typing import Any

from ..errors import ConfigError

__all__ = ["TENSORBOARD_EXTRA", "require_tensorboard", "summary_writer", "log_validation"]

TENSORBOARD_EXTRA = "TensorBoard logging needs the 'tensorboard' extra: pip install -e '.[tensorboard]'"


def require_tensorboard() -> Any:
    """``torch.utils.tensorboard.SummaryWriter``, or :class:`ConfigError` naming the extra when the
    tensorboard package is missing."""
    try:
        from torch.utils.tensorboard import SummaryWriter
    except ImportError as e:
        raise ConfigError(f"{TENSORBOARD_EXTRA} ({e})") from None
    return SummaryWriter


def summary_writer(log_dir: str | os.PathLike) -> Any:
    """A TensorBoard ``SummaryWriter`` on ``log_dir`` (see :func:`require_tensorboard`)."""
    return require_tensorboard()(log_dir=str(log_dir), flush_secs=10)


def log_validation(log_dir: str | os.PathLike, report: Mapping[str, Any], step: int) -> None:
    """Add an evaluation's figures (``EvalReport.to_dict()``: the held-out loss, the mean and per-category
    errors) to the TensorBoard log in ``log_dir`` at ``step`` (the training's last iteration)."""
    figures: dict[str, Any] = {
        "validation/heldout_loss": report.get("heldout_loss"),
        "validation/chance_loss": report.get("chance_loss"),
        "validation/mean_t_cm": report.get("mean_t_cm"),
        "validation/mean_R_deg": report.get("mean_R_deg"),
    }
    for c in report.get("categories", []):
        for key in ("t_cm", "R_deg", "baseline_t_cm", "baseline_R_deg"):
            figures[f"validation/{key}/{c['category']}"] = c.get(key)
    writer = summary_writer(log_dir)
    try:
        for tag, v in figures.items():
            if isinstance(v, (int, float)) and math.isfinite(v):
                writer.add_scalar(tag, float(v), step)
    finally:
        writer.close()
