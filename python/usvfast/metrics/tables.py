"""Readers of the CSV tables a simulated recording and a pipeline run write: the ground truth
(`truth.csv`), the tracks, the detections, the USV poses and the innovations.

Every reader returns a table of numpy columns (one row per CSV line), skips damaged lines
(a missing column, a non-number, a non-finite required value; an empty optional value, e.g.
a LiDAR detection's score, reads as NaN) with one `DamagedRecordsWarning` and the
count in `.skipped` (a line that is not UTF-8 or longer than 64 KiB costs that line), and
raises ValueError naming the path when it is missing or not a regular file, or naming the
missing header columns. Positions are local NED metres (north, east); times UNIX seconds.

Example::

    truth = read_truth("sim/truth.csv")
    tracks = read_tracks("out/tracks.csv")
    truth.positions[truth.object_id == 3]
"""

from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from usvfast._damage import DamageCounter
from usvfast._files import OVERLONG_LINE, bounded_lines, regular_file

TRUTH_COLUMNS = ("time", "object_id", "kind", "north", "east")
TRACK_COLUMNS = ("time", "track_id", "north", "east", "v_north", "v_east")
TRACK_COV_COLUMNS = ("cov_nn", "cov_ne", "cov_ee")
DETECTION_COLUMNS = ("time", "sensor", "north", "east")
NAV_COLUMNS = ("time", "north", "east", "heading_deg")
INNOVATION_COLUMNS = ("time", "track_id", "sensor", "nis", "dof")


def _read(
    path: str | Path, need: tuple[str, ...], optional: tuple[str, ...], text: tuple[str, ...]
) -> tuple[dict[str, np.ndarray], int]:
    p = regular_file(path, "path")
    damage = DamageCounter(str(p), what="damaged line(s)")
    with p.open("rb") as fh:
        lines = bounded_lines(fh)
        first = next(lines, b"").decode("utf-8", "replace")
        header = [h.strip() for h in next(csv.reader([first]), [])]
        missing = [c for c in need if c not in header]
        if missing:
            raise ValueError(f"{p}: missing column(s) {', '.join(missing)} (header {header})")
        cols = [c for c in (*need, *optional) if c in header]
        index = [header.index(c) for c in cols]
        out: dict[str, list] = {c: [] for c in cols}
        numeric = [c for c in need if c not in text]  # required numbers must be finite
        for lineno, raw in enumerate(lines, start=2):
            try:
                row = next(csv.reader([raw.decode("utf-8")]), [])
            except (UnicodeDecodeError, csv.Error):
                damage.add(f"line {lineno}")
                continue
            if raw == OVERLONG_LINE:
                damage.add(f"line {lineno}: over-long")
                continue
            if not row:
                continue
            try:
                vals = [
                    row[i].strip() if i < len(row) or c in need else ""
                    for c, i in zip(cols, index, strict=True)
                ]
                nums = [
                    v if c in text else (np.nan if c in optional and v == "" else float(v))
                    for c, v in zip(cols, vals, strict=True)
                ]
            except (IndexError, ValueError):
                damage.add(f"line {lineno}")
                continue
            if not all(np.isfinite(v) for c, v in zip(cols, nums, strict=True) if c in numeric):
                damage.add(f"line {lineno}: non-finite")
                continue
            for c, v in zip(cols, nums, strict=True):
                out[c].append(v)
    damage.warn(stacklevel=4)
    arrays = {c: np.array(v, dtype=str if c in text else np.float64) for c, v in out.items()}
    return arrays, damage.count


@dataclass(frozen=True)
class Truth:
    """Ground truth: time (N,) s, object_id (N,) int, kind (N,) str, positions (N, 2) NED m.
    When the file names its objects with text ids (e.g. "bottle1"), object_id holds their
    index in `names` (sorted), and `name(i)` gives the text back."""

    time: np.ndarray
    object_id: np.ndarray
    kind: np.ndarray
    positions: np.ndarray
    skipped: int = 0
    names: tuple[str, ...] = ()

    def name(self, object_id: int) -> str:
        """The file's id of an object (its text id, or the integer as text)."""
        return self.names[object_id] if self.names else str(object_id)

    def kinds(self) -> dict[int, str]:
        """Kind of every object id."""
        ids, first = np.unique(self.object_id, return_index=True)
        return {int(i): str(self.kind[f]) for i, f in zip(ids, first, strict=True)}


@dataclass(frozen=True)
class Tracks:
    """Track rows: time (N,) s, track_id (N,) int, positions (N, 2) NED m, velocities (N, 2)
    m/s, covariances (N, 2, 2) m² of the position (NaN when the file has none)."""

    time: np.ndarray
    track_id: np.ndarray
    positions: np.ndarray
    velocities: np.ndarray
    covariances: np.ndarray
    skipped: int = 0


@dataclass(frozen=True)
class Detections:
    """Detections handed to the tracker: time (N,) s, sensor (N,) str, positions (N, 2) NED m,
    covariances (N, 2, 2) m² (NaN when absent), score (N,) (NaN when absent)."""

    time: np.ndarray
    sensor: np.ndarray
    positions: np.ndarray
    covariances: np.ndarray
    score: np.ndarray
    skipped: int = 0


@dataclass(frozen=True)
class Nav:
    """USV poses: time (N,) s, positions (N, 2) NED m, heading_deg (N,) clockwise from north."""

    time: np.ndarray
    positions: np.ndarray
    heading_deg: np.ndarray
    skipped: int = 0


@dataclass(frozen=True)
class Innovations:
    """Track updates with a detection: time (N,) s, track_id (N,) int, sensor (N,) str,
    nis (N,) the normalised innovation squared, dof (N,) int its degrees of freedom, gate (N,)
    the tracker's gate probability P_G that truncated it (NaN: not gated; None: unknown, as
    not gated)."""

    time: np.ndarray
    track_id: np.ndarray
    sensor: np.ndarray
    nis: np.ndarray
    dof: np.ndarray
    skipped: int = 0
    gate: np.ndarray | None = None

    def gate_of(self, keep: np.ndarray) -> np.ndarray | None:
        """gate[keep] (a row mask or indices), None when the gate is unknown."""
        return None if self.gate is None else self.gate[keep]


def _cov(a: dict[str, np.ndarray], n: int) -> np.ndarray:
    if not all(c in a for c in TRACK_COV_COLUMNS):
        return np.full((n, 2, 2), np.nan)
    nn, ne, ee = (a[c] for c in TRACK_COV_COLUMNS)
    return np.stack([np.stack([nn, ne], -1), np.stack([ne, ee], -1)], -2).reshape(n, 2, 2)


def read_truth(path: str | Path) -> Truth:
    """Read `truth.csv` (columns time,object_id,kind,north,east[,lat,lon]); object ids may be
    integers or text."""
    a, skipped = _read(path, TRUTH_COLUMNS, (), ("kind", "object_id"))
    raw = a["object_id"]
    names: tuple[str, ...] = ()
    try:
        ids = np.array([int(v) for v in raw], dtype=np.int64)
    except ValueError:  # text ids: number them in sorted order
        uniq, ids = np.unique(raw, return_inverse=True)
        ids = ids.astype(np.int64)
        names = tuple(str(u) for u in uniq)
    return Truth(
        time=a["time"],
        object_id=ids.reshape(-1),
        kind=a["kind"],
        positions=np.column_stack([a["north"], a["east"]]).reshape(-1, 2),
        skipped=skipped,
        names=names,
    )


def read_tracks(path: str | Path) -> Tracks:
    """Read `tracks.csv` (time,track_id,north,east,v_north,v_east[,lat,lon,cov_nn,cov_ne,
    cov_ee])."""
    a, skipped = _read(path, TRACK_COLUMNS, TRACK_COV_COLUMNS, ())
    n = len(a["time"])
    return Tracks(
        time=a["time"],
        track_id=a["track_id"].astype(np.int64),
        positions=np.column_stack([a["north"], a["east"]]).reshape(-1, 2),
        velocities=np.column_stack([a["v_north"], a["v_east"]]).reshape(-1, 2),
        covariances=_cov(a, n),
        skipped=skipped,
    )


def read_detections(path: str | Path) -> Detections:
    """Read `detections.csv` (time,sensor,north,east[,lat,lon,cov_nn,cov_ne,cov_ee,score])."""
    a, skipped = _read(path, DETECTION_COLUMNS, (*TRACK_COV_COLUMNS, "score"), ("sensor",))
    n = len(a["time"])
    return Detections(
        time=a["time"],
        sensor=a["sensor"],
        positions=np.column_stack([a["north"], a["east"]]).reshape(-1, 2),
        covariances=_cov(a, n),
        score=a.get("score", np.full(n, np.nan)),
        skipped=skipped,
    )


def read_nav(path: str | Path) -> Nav:
    """Read `nav.csv` (time,north,east,heading_deg[,lat,lon,roll_deg,pitch_deg])."""
    a, skipped = _read(path, NAV_COLUMNS, (), ())
    return Nav(
        time=a["time"],
        positions=np.column_stack([a["north"], a["east"]]).reshape(-1, 2),
        heading_deg=a["heading_deg"],
        skipped=skipped,
    )


def read_innovations(path: str | Path) -> Innovations:
    """Read `innovations.csv` (time,track_id,sensor,nis,dof[,gate])."""
    a, skipped = _read(path, INNOVATION_COLUMNS, ("gate",), ("sensor",))
    gate = a.get("gate")
    if gate is not None and not np.all(np.isnan(gate) | ((gate > 0) & (gate <= 1))):
        raise ValueError(f"{path}: column gate: a gate probability must lie in (0, 1]")
    return Innovations(
        time=a["time"],
        track_id=a["track_id"].astype(np.int64),
        sensor=a["sensor"],
        nis=a["nis"],
        dof=a["dof"].astype(np.int64),
        skipped=skipped,
        gate=gate,
    )
