"""Skip-and-count bookkeeping shared by every field-data reader: one warning class (with
area-specific subclasses such as `usvfast.lidar.LidarDataWarning` and
`usvfast.bearing.SkippedRowsWarning`) and a counter that keeps the first few reasons."""

from __future__ import annotations

import warnings

__all__ = ["DamageCounter", "DamagedRecordsWarning"]


class DamagedRecordsWarning(UserWarning):
    """A field-data reader skipped damaged records (the count is on the result)."""


class DamageCounter:
    """Count damaged records and keep the first few reasons for the warning message.

    source: what is being read (a path, a topic), the start of the message. what: the noun of
    the count (default "damaged record(s)"). category: the warning class emitted, a
    DamagedRecordsWarning or a subclass."""

    def __init__(
        self,
        source: str,
        *,
        what: str = "damaged record(s)",
        category: type[DamagedRecordsWarning] = DamagedRecordsWarning,
    ) -> None:
        self.source = source
        self.what = what
        self.category = category
        self.count = 0
        self.reasons: list[str] = []

    def add(self, reason: str) -> None:
        """Record one damaged (skipped) record."""
        self.count += 1
        if len(self.reasons) < 3:
            self.reasons.append(reason)

    def warn(self, stacklevel: int = 3) -> None:
        """Emit one warning of `category` if anything was skipped (the default stacklevel
        points at the caller of the reader that calls `warn`)."""
        if self.count:
            shown = "; ".join(self.reasons)
            more = "; ..." if self.count > len(self.reasons) else ""
            warnings.warn(
                f"{self.source}: skipped {self.count} {self.what} ({shown}{more})",
                self.category,
                stacklevel=stacklevel,
            )
