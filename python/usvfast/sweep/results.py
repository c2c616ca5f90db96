"""The results table of a sweep: one Parquet row per job, written as jobs finish.

Finished rows go to small part files (`DIR/results.parts/part-NNNNNN.parquet`, each written to
a temporary name and renamed, so a crash never leaves half a file); `DIR/results.parquet` is
the union of the parts, one row per job id, rewritten at the end. A resumed sweep reads the
parts and skips every job already in them.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from usvfast._extras import require

pd = require("pandas", "cluster", "sweep results")

FINISHED = ("ok", "error")


class ResultsStore:
    """Incremental, crash-safe results of one sweep folder. `add(row)` buffers a row and writes
    a part every `flush_every` rows; `flush()` writes what is buffered; `table()` is every
    row written so far, one per job id (the first written wins)."""

    def __init__(self, out_dir: str | Path, flush_every: int = 8) -> None:
        self.out_dir = Path(out_dir)
        self.parts = self.out_dir / "results.parts"
        self.parts.mkdir(parents=True, exist_ok=True)
        self.flush_every = flush_every
        self._buffer: list[dict[str, Any]] = []
        self._next = 1 + max((int(p.stem.split("-")[1]) for p in self._part_files()), default=0)

    def _part_files(self) -> list[Path]:
        return sorted(self.parts.glob("part-*.parquet"))

    def add(self, row: dict[str, Any]) -> None:
        self._buffer.append(row)
        if len(self._buffer) >= self.flush_every:
            self.flush()

    def flush(self) -> None:
        if not self._buffer:
            return
        path = self.parts / f"part-{self._next:06d}.parquet"
        tmp = path.with_suffix(".tmp")
        pd.DataFrame(self._buffer).to_parquet(tmp, index=False)
        os.replace(tmp, path)
        self._next += 1
        self._buffer.clear()

    def table(self) -> Any:
        frames = [pd.read_parquet(p) for p in self._part_files()]
        if self._buffer:
            frames.append(pd.DataFrame(self._buffer))
        frames = [f for f in frames if len(f)]
        if not frames:
            return pd.DataFrame({"job_id": pd.Series(dtype=str), "status": pd.Series(dtype=str)})
        return pd.concat(frames, ignore_index=True).drop_duplicates("job_id", keep="first")

    def finished_ids(self, retry_failed: bool = False) -> set[str]:
        """Job ids that a resumed sweep must not run again: every "ok" row, and the "error"
        rows too unless `retry_failed` (a deterministic error would only repeat)."""
        t = self.table()
        done = ("ok",) if retry_failed else FINISHED
        return set(t.loc[t["status"].isin(done), "job_id"])

    def drop(self, job_ids: set[str]) -> None:
        """Remove rows of these job ids from the parts (before re-running them)."""
        if not job_ids:
            return
        self.flush()
        for p in self._part_files():
            t = pd.read_parquet(p)
            keep = t[~t["job_id"].isin(job_ids)]
            if len(keep) != len(t):
                tmp = p.with_suffix(".tmp")
                keep.to_parquet(tmp, index=False)
                os.replace(tmp, p)

    def write_table(self) -> Path:
        """Write DIR/results.parquet (one row per job) and return its path."""
        self.flush()
        path = self.out_dir / "results.parquet"
        tmp = path.with_suffix(".tmp")
        self.table().to_parquet(tmp, index=False)
        os.replace(tmp, path)
        return path
