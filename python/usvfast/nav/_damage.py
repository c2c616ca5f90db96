"""File checks of the `usvfast.nav` readers; re-exports the skip-and-count bookkeeping."""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path
from typing import Any

# The warning and the counter live in usvfast._damage (shared with lidar and bearing).
from usvfast._damage import DamageCounter, DamagedRecordsWarning
from usvfast._files import bounded_lines, regular_file

__all__ = ["DamageCounter", "DamagedRecordsWarning", "check_file", "iter_lines"]


def iter_lines(source: Any) -> Iterator[Any]:
    """The lines of `source`: a path (str or os.PathLike, read as bytes, closed at the end)
    or any iterable of lines (str, bytes or (time, line) pairs), passed through. A path that is
    not a regular file is refused (ValueError); a line longer than `MAX_LINE_BYTES` comes out
    as `OVERLONG_LINE`, which readers count as damaged."""
    if isinstance(source, str | os.PathLike):
        with regular_file(source, "source").open("rb") as fh:
            yield from bounded_lines(fh)
    else:
        yield from source


def check_file(path: Path | str, label: str, *, directory: bool = False) -> Path:
    """Return `path` as a Path, or raise ValueError naming `label` when it does not exist or
    is not a regular file (a directory is accepted with `directory`: ROS 2 bag folders)."""
    return regular_file(path, label, directory=directory)
