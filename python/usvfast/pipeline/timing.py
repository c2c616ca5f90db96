"""Per-stage wall-clock timing of the pipeline (reader, pose, each LiDAR and camera stage,
tracker): totals and call counts, a few floats per stage whatever the recording's length."""

from __future__ import annotations

import time
from collections.abc import Iterator
from contextlib import contextmanager

__all__ = ["StageTimer"]


class StageTimer:
    """Accumulates seconds and calls per named stage (e.g. "lidar.prefilter")."""

    def __init__(self) -> None:
        self.seconds: dict[str, float] = {}
        self.calls: dict[str, int] = {}

    def add(self, stage: str, seconds: float) -> None:
        """Add `seconds` (wall clock) to `stage`."""
        self.seconds[stage] = self.seconds.get(stage, 0.0) + seconds
        self.calls[stage] = self.calls.get(stage, 0) + 1

    @contextmanager
    def __call__(self, stage: str) -> Iterator[None]:
        """`with timer("stage"): ...` times the block."""
        t0 = time.perf_counter()
        try:
            yield
        finally:
            self.add(stage, time.perf_counter() - t0)

    @property
    def total(self) -> float:
        """Sum over stages, seconds."""
        return sum(self.seconds.values())

    def table(self) -> list[tuple[str, float, int]]:
        """(stage, seconds, calls) rows in the order the stages first ran."""
        return [(k, v, self.calls[k]) for k, v in self.seconds.items()]

    def as_dict(self) -> dict[str, dict[str, float]]:
        """{stage: {"seconds": s, "calls": n, "ms_per_call": ms}} for summary.json."""
        return {
            k: {"seconds": v, "calls": self.calls[k], "ms_per_call": 1e3 * v / self.calls[k]}
            for k, v in self.seconds.items()
        }
