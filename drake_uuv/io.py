"""Atomic file output: write to a temporary file in the same folder, then rename."""

import json
import os
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import IO, Any

import numpy as np


def write_atomic(path: Path, write: Callable[[IO[bytes]], None]) -> Path:
    """Calls ``write(file)`` on a temporary file beside ``path`` and renames it into place.

    A reader never sees a half-written file, and an interrupted run leaves the old file (or
    none), never a truncated one.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, temporary = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        os.fchmod(fd, 0o666 & ~_UMASK)  # mkstemp makes 0600; outputs get the usual mode
        with os.fdopen(fd, "wb") as file:
            write(file)
            file.flush()
            os.fsync(file.fileno())
        os.replace(temporary, path)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise
    return path


def _read_umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


# Read once at import: os.umask is process-wide, and setting it from worker threads would race.
_UMASK = _read_umask()


def write_text_atomic(path: Path, text: str) -> Path:
    """Writes UTF-8 text atomically."""
    return write_atomic(path, lambda f: f.write(text.encode()))


def write_json_atomic(path: Path, data: Any) -> Path:
    """Writes JSON (indented, keys in order given) atomically."""
    return write_text_atomic(path, json.dumps(data, indent=2) + "\n")


def write_npz_atomic(path: Path, arrays: dict[str, np.ndarray]) -> Path:
    """Writes a compressed ``.npz`` atomically."""
    return write_atomic(path, lambda f: np.savez_compressed(f, **arrays))


def save_figure_atomic(figure: Any, path: Path, **kwargs: Any) -> Path:
    """Saves a matplotlib figure atomically (format from the suffix)."""
    fmt = Path(path).suffix.lstrip(".")
    return write_atomic(path, lambda f: figure.savefig(f, format=fmt, **kwargs))
