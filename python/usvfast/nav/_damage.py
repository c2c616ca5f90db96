"""File checks of the `usvfast.nav` readers; re-exports the skip-and-count bookkeeping."""

from __future__ import annotations

from pathlib import Path

# The warning and the counter live in usvfast._damage (shared with lidar and bearing).
from usvfast._damage import DamageCounter, DamagedRecordsWarning

__all__ = ["DamageCounter", "DamagedRecordsWarning", "check_file"]


def check_file(path: Path | str, label: str) -> Path:
    """Return `path` as a Path, or raise ValueError naming `label` when it does not exist."""
    p = Path(path)
    if not p.exists():
        raise ValueError(f"{label}: no such file or directory: {p}")
    return p
