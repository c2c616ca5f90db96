"""Skip-and-count bookkeeping shared by the field-data readers of `usvfast.nav`."""

from __future__ import annotations

import warnings
from pathlib import Path

# One warning class for every reader of usvfast.nav (defined with the NMEA reader).
from usvfast.nav.nmea import DamagedRecordsWarning

__all__ = ["DamageCounter", "DamagedRecordsWarning", "check_file"]


class DamageCounter:
    """Count damaged records and keep the first few reasons for the warning message."""

    def __init__(self, source: str) -> None:
        self.source = source
        self.count = 0
        self.reasons: list[str] = []

    def add(self, reason: str) -> None:
        """Record one damaged (skipped) record."""
        self.count += 1
        if len(self.reasons) < 3:
            self.reasons.append(reason)

    def warn(self, stacklevel: int = 3) -> None:
        """Emit one DamagedRecordsWarning if anything was skipped."""
        if self.count:
            shown = "; ".join(self.reasons)
            more = "; ..." if self.count > len(self.reasons) else ""
            warnings.warn(
                f"{self.source}: skipped {self.count} damaged record(s) ({shown}{more})",
                DamagedRecordsWarning,
                stacklevel=stacklevel,
            )


def check_file(path: Path | str, label: str) -> Path:
    """Return `path` as a Path, or raise ValueError naming `label` when it does not exist."""
    p = Path(path)
    if not p.exists():
        raise ValueError(f"{label}: no such file or directory: {p}")
    return p
