"""Writing outputs atomically: a file appears whole at its path or not at all.

Checkpoints, datasets, results, reports and plots are written through :func:`atomic_file`: to a
temporary file beside the target, flushed, then renamed over it, so an error, an interrupt or a full
disk leaves the older file as it was. :func:`check_output_path` refuses, before any
work, a path that cannot be written.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import BinaryIO

from .fields import SceneError

__all__ = ["WriteError", "check_output_path", "atomic_file", "atomic_write_bytes", "atomic_write_text"]


class WriteError(OSError, SceneError):
    """An output that could not be written (a file-size limit, a full disk, an I/O error): an ``OSError``
    with the cause's ``errno``, and, like every :class:`SceneError`, a one-line message (naming the file)
    that the command line prints without a traceback. The older file at that path is left as it was."""


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def check_output_path(path: str | os.PathLike, what: str, folder: bool = False) -> None:
    """Fail early, with a one-line :class:`SceneError`, when ``path`` cannot be written: an existing
    folder where a file is meant (or a file where a folder is), a regular file among its parents, or a
    nearest existing parent that is not writable."""
    p = Path(path)
    if p.exists() and p.is_dir() != folder:
        kind = "a folder" if p.is_dir() else "a file"
        raise SceneError(f"{what} {p}: is {kind}; expected {'a folder' if folder else 'a file'} to write")
    parent = p if folder else p.parent
    while not parent.exists():
        parent = parent.parent
    if not parent.is_dir():
        raise SceneError(f"{what} {p}: {parent} is a file, not a folder")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise SceneError(f"{what} {p}: the folder {parent} is not writable")


@contextmanager
def atomic_file(path: str | os.PathLike) -> Iterator[BinaryIO]:
    """A binary file that becomes ``path`` when the block ends (written to a temporary file beside it,
    then renamed); an error or an interrupt inside the block removes it and leaves the old file. The
    file gets the usual permissions (0666 less the umask), not the temporary file's 0600."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as f:
            yield f
            f.flush()
            os.fsync(f.fileno())
        os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, path)
    except OSError as e:
        Path(tmp).unlink(missing_ok=True)
        # a failure of writing this file (EFBIG, ENOSPC, EIO: no file named) or of renaming it; an error
        # that names another file came from the caller's own work in the block and is left as it is
        if isinstance(e, WriteError) or e.filename not in (None, tmp):
            raise
        err = WriteError(f"{path}: could not be written ({e.strerror or e}); {_left(path)}")
        err.errno = e.errno
        raise err from e
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def _left(path: Path) -> str:
    """What a failed atomic write left at ``path``."""
    return "the earlier file is unchanged" if path.exists() else "nothing was written"


def atomic_write_bytes(path: str | os.PathLike, data: bytes) -> None:
    """Write ``data`` to ``path`` through a temporary file and a rename: a failure leaves the old file."""
    with atomic_file(path) as f:
        f.write(data)


def atomic_write_text(path: str | os.PathLike, text: str) -> None:
    """Write text atomically (see :func:`atomic_write_bytes`)."""
    atomic_write_bytes(path, text.encode("utf-8"))
