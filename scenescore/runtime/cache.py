"""The user's cache folder: what the library keeps between runs on this machine (compiled kernels, the
tidy calibration of a model measured at its first tidy), never anything a result depends on being there.

``SCENESCORE_CACHE_DIR`` names it; else ``$XDG_CACHE_HOME/scenescore``, else ``~/.cache/scenescore``.
Each use keeps its files in a sub-folder of its own (:func:`cache_folder`); an entry is written through
a temporary file and a rename, so a run killed while writing leaves none half-written.
"""

from __future__ import annotations

import os
from pathlib import Path

__all__ = ["ENV", "cache_root", "cache_folder"]

ENV = "SCENESCORE_CACHE_DIR"


def cache_root() -> Path:
    """The cache folder (not created): ``SCENESCORE_CACHE_DIR``, else the platform's user cache."""
    given = os.environ.get(ENV, "").strip()
    if given:
        return Path(given).expanduser()
    base = os.environ.get("XDG_CACHE_HOME", "").strip()
    return (Path(base).expanduser() if base else Path.home() / ".cache") / "scenescore"


def cache_folder(kind: str) -> Path:
    """The sub-folder ``kind`` of the cache folder, created when missing."""
    folder = cache_root() / kind
    folder.mkdir(parents=True, exist_ok=True)
    return folder
