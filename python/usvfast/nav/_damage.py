"""File checks of the `usvfast.nav` readers; re-exports the skip-and-count bookkeeping."""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path
from typing import Any

# The warning and the counter live in usvfast._damage (shared with lidar and bearing).
from usvfast._damage import DamageCounter, DamagedRecordsWarning

__all__ = ["DamageCounter", "DamagedRecordsWarning", "check_file", "iter_lines"]


def iter_lines(source: Any) -> Iterator[Any]:
    """The lines of `source`: a path (str or os.PathLike, read as bytes, closed at the end)
    or any iterable of lines (str, bytes or (time, line) pairs), passed through."""
    if isinstance(source, str | os.PathLike):
        with Path(source).open("rb") as fh:
            yield from fh
    else:
        yield from source


def check_file(path: Path | str, label: str) -> Path:
    """Return `path` as a Path, or raise ValueError naming `label` when it does not exist."""
    p = Path(path)
    if not p.exists():
        raise ValueError(f"{label}: no such file or directory: {p}")
    return p
