"""Moving vessels among the LiDAR's line structures: one detection per vessel, near its centre.

The thesis's line-of-sight filter (section 3.3) removes every point near a line segment, so a
vessel's hull, whose sides are line segments a few metres long, is removed like a quay wall;
the few points left at its corners cluster metres off its centre. `VesselFinder` looks at the
removed points of the last frame of every clustering cycle (world frame, NED m):

1. grid them (`cell` m) and group the occupied cells (single linkage at `link` m: the
   connected components of their neighbour graph, SciPy);
2. a group is a vessel-sized candidate when its extent along its axis (the long side of the
   rectangle fitted by L-shape fitting: the hull's seen side, also for an L of side and bow) lies in
   [`min_length`, `max_length`] m and across it ≤ `beam` + `across_margin` m (a quay or a pier
   is longer; a floating object leaves no lines);
3. each candidate is matched to one of the previous cycle's (centroid within `match_distance`
   m, axes within ~37°); the matched chain is its trail. Its ends along the axis (the cells
   within half a metre of the extreme ones) are compared with the trail's oldest entry at
   least `min_baseline` s older: an end that is not clipped by the sensor's range in both
   gives a speed. Static structure (walls, moored boats) keeps its ends in place; a vessel
   moves them at its speed. A candidate whose speed is ≥ `min_speed` m/s on `min_moving`
   consecutive cycles is a vessel;
4. its detection: the hull's seen side is the nearest cell centre to the sensor across the
   axis (the centre, not the cell's near edge: a point lies anywhere in its cell, so the edge
   placed the side half a cell too near), so the centre lies half the `beam` beyond it;
   along the axis it is the middle of the seen ends when both are seen, else half the
   hull's length from the one seen end. That length is
   learned per trail: the median of the group's along-axis extents over the cycles of its
   trail in which neither end was clipped (the hull seen whole; the median, not the longest,
   since one cycle's group now and then reaches 0.6-0.9 m beyond the hull), else the
   configured `length`; never less than the extent seen now. Covariance diag(along²,
   across²) in the (axis, across) frame: `end_std` m along with both ends seen now or a
   learned length (both ends were seen on the trail), `length_std` m with one end and the
   configured length, and `beam_std` m across (the unknown beam and hull shape, not sensor
   noise).

The moored boats of a harbour lie alongside the quay: their cells join the quay's into one
group too long to be a candidate, and they do not move.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from usvfast._validate import as_float_array, real

__all__ = ["VesselCandidate", "VesselFinder", "single_linkage"]


#: The unclipped extents a trail keeps for its hull length (memory stays bounded on a vessel
#: followed for hours; 50 cycles are 20 s of the LiDAR's 2.5 Hz clustering).
MAX_EXTENTS = 50


@dataclass(eq=False)
class VesselCandidate:
    """One vessel-sized group of line points in one cycle.

    time : UNIX s; centroid : (2,) NED m; axis : (2,) unit vector along the hull (NED);
    ends : (2, 2) the end points at the low and high along-axis coordinate, NED m;
    clipped : (2,) whether each end lies within `clip_margin` of the sensor's range (maybe
    cut off); cells : (k, 2) occupied cell centres, NED m; n_points : points in the group;
    trail : the matched candidates of earlier cycles (time, ends (2, 2), clipped (2,)),
    oldest first; moving : consecutive cycles with a speed ≥ min_speed; speed : m/s of the
    last estimate (NaN when no end could be compared); velocity : (2,) NED m/s of the last
    estimate; extents : the along-axis extents m of this group and of its trail's groups
    that were seen with neither end clipped, oldest first (the newest `MAX_EXTENTS`).
    """

    time: float
    centroid: np.ndarray
    axis: np.ndarray
    ends: np.ndarray
    clipped: np.ndarray
    cells: np.ndarray
    n_points: int
    trail: list[tuple[float, np.ndarray, np.ndarray]] = field(default_factory=list)
    moving: int = 0
    speed: float = float("nan")
    velocity: np.ndarray = field(default_factory=lambda: np.zeros(2))
    extents: list[float] = field(default_factory=list)

    @property
    def learned_length(self) -> float:
        """The hull's length m learned from the trail: the median of `extents` (NaN when
        empty)."""
        return float(np.median(self.extents)) if self.extents else float("nan")


@dataclass
class VesselFinder:
    """Finds moving vessels among the points that the line-of-sight filter removed (module
    doc). Lengths in metres, speeds m/s, times s. `update(points, time, sensor)` returns the
    candidates of this cycle judged to be vessels, and `detection(candidate, sensor)` their
    (centre (2,), covariance (2, 2)) in NED metres."""

    radius: float = 10.0
    cell: float = 0.2
    link: float = 0.8
    min_points: int = 40
    min_length: float = 2.0
    max_length: float = 9.0
    beam: float = 2.2
    across_margin: float = 1.5
    length: float = 6.0
    min_speed: float = 0.8
    min_baseline: float = 0.7
    max_baseline: float = 1.3
    min_moving: int = 2
    match_distance: float = 4.0
    clip_margin: float = 0.8
    end_std: float = 0.4
    length_std: float = 0.8
    beam_std: float = 0.35
    _previous: list[VesselCandidate] = field(default_factory=list, init=False, repr=False)

    def __post_init__(self) -> None:
        for name in (
            "radius",
            "cell",
            "link",
            "max_length",
            "beam",
            "length",
            "min_speed",
            "min_baseline",
            "max_baseline",
            "end_std",
            "length_std",
            "beam_std",
        ):
            setattr(self, name, real(name, getattr(self, name), positive=True))
        for name in ("min_length", "across_margin", "match_distance", "clip_margin"):
            setattr(self, name, real(name, getattr(self, name), low=0.0))
        for name in ("min_points", "min_moving"):
            v = getattr(self, name)
            if isinstance(v, bool) or int(v) != v or v < 1:
                raise ValueError(f"{name}: expected an integer >= 1, got {v!r}")
        if not self.min_baseline < self.max_baseline:
            raise ValueError(
                f"min_baseline/max_baseline: expected min < max, got "
                f"{self.min_baseline}, {self.max_baseline}"
            )

    def reset(self) -> None:
        """Forget the previous cycles."""
        self._previous = []

    def candidates(
        self, points: np.ndarray, time: float, sensor: np.ndarray
    ) -> list[VesselCandidate]:
        """Vessel-sized groups (module doc, steps 1-2) of `points` (n, 2) NED m seen from
        `sensor` (2,) NED m at `time` s, not yet matched to earlier cycles."""

        pts = as_float_array("points", points, ndim=2).reshape(-1, 2)
        sensor = as_float_array("sensor", sensor, ndim=1)
        if sensor.shape != (2,):
            raise ValueError(f"sensor: expected (north, east), got shape {sensor.shape}")
        if len(pts) < self.min_points:
            return []
        keys, counts = np.unique(
            np.floor(pts / self.cell).astype(np.int64), axis=0, return_counts=True
        )
        cells = (keys + 0.5) * self.cell
        labels = single_linkage(cells, self.link)
        out = []
        for k in range(int(labels.max()) + 1 if len(labels) else 0):
            sel = labels == k
            n = int(counts[sel].sum())
            if n < self.min_points:
                continue
            c, w = cells[sel], counts[sel].astype(np.float64)
            centroid = (c * w[:, None]).sum(axis=0) / w.sum()
            if len(c) < 3:
                continue
            axis = _hull_axis(c)
            a = (c - centroid) @ axis
            across = (c - centroid) @ np.array([-axis[1], axis[0]])
            along_extent = float(a.max() - a.min()) + self.cell
            across_extent = float(across.max() - across.min()) + self.cell
            if not (self.min_length <= along_extent <= self.max_length):
                continue
            if across_extent > self.beam + self.across_margin:
                continue
            ends = np.array(
                [c[a <= a.min() + 0.5].mean(axis=0), c[a >= a.max() - 0.5].mean(axis=0)]
            )
            reach = self.radius - self.clip_margin
            clipped = np.hypot(*(ends - sensor).T) >= reach
            cand = VesselCandidate(float(time), centroid, axis, ends, clipped, c, n)
            if not clipped.any():
                cand.extents = [along_extent]
            out.append(cand)
        return out

    def update(self, points: np.ndarray, time: float, sensor: np.ndarray) -> list[VesselCandidate]:
        """One cycle (module doc, steps 1-3): the candidates of `points` (n, 2) NED m seen
        from `sensor` (2,) NED m at `time` UNIX s, matched to the previous cycle's; returns
        those that are moving vessels."""
        time = real("time", time)
        now = self.candidates(points, time, sensor)
        used: set[int] = set()
        for cand in now:
            best, best_d = -1, self.match_distance
            for i, prev in enumerate(self._previous):
                d = float(np.hypot(*(cand.centroid - prev.centroid)))
                if i in used or d > best_d or abs(float(cand.axis @ prev.axis)) < 0.8:
                    continue
                best, best_d = i, d
            if best < 0:
                continue
            used.add(best)
            prev = self._previous[best]
            ends, clipped = prev.ends, prev.clipped
            if float(cand.axis @ prev.axis) < 0:  # the same axis, the other way round
                ends, clipped = ends[::-1], clipped[::-1]
            trail = [(t, e, c) for t, e, c in prev.trail if time - t <= self.max_baseline]
            cand.trail = [*trail, (prev.time, ends, clipped)]
            cand.moving = prev.moving
            cand.velocity = prev.velocity
            cand.extents = [*prev.extents, *cand.extents][-MAX_EXTENTS:]
            self._judge(cand)
        self._previous = now
        # a group with both ends maybe cut off tells nothing of where the hull's centre is
        return [c for c in now if c.moving >= self.min_moving and not c.clipped.all()]

    def _judge(self, cand: VesselCandidate) -> None:
        """Speed of `cand`'s unclipped ends against its trail's oldest entry within
        [min_baseline, max_baseline] s; updates `moving`, `speed`, `velocity`."""
        old = [e for e in cand.trail if self.min_baseline <= cand.time - e[0] <= self.max_baseline]
        if not old:
            return
        t0, ends0, clipped0 = old[0]
        dt = cand.time - t0
        ok = ~(cand.clipped | clipped0)
        if not ok.any():
            return  # both ends maybe cut off: no evidence either way; keep the count
        v = ((cand.ends - ends0)[ok] / dt).mean(axis=0)
        cand.velocity = v
        cand.speed = float(np.hypot(v[0], v[1]))
        cand.moving = cand.moving + 1 if cand.speed >= self.min_speed else 0

    def hull_length(self, cand: VesselCandidate) -> float:
        """The hull's length m assumed for `cand` (module doc, step 4): its trail's
        `learned_length` when it has one, else the configured `length`, and never less than the
        group's along-axis extent seen now."""
        a = (cand.cells - cand.centroid) @ cand.axis
        seen = float(a.max() - a.min()) + self.cell
        learned = cand.learned_length
        return max(self.length if np.isnan(learned) else float(learned), seen)

    def detection(self, cand: VesselCandidate, sensor: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Centre (2,) NED m and covariance (2, 2) m² of a vessel candidate seen from
        `sensor` (2,) NED m (module doc, step 4)."""
        sensor = as_float_array("sensor", sensor, ndim=1)
        u = cand.axis
        n = np.array([-u[1], u[0]])
        if float((cand.centroid - sensor) @ n) < 0:
            n = -n  # across axis pointing away from the sensor
        a = (cand.cells - cand.centroid) @ u
        c = (cand.cells - cand.centroid) @ n
        near = float(c.min())
        across = near + self.beam / 2
        lo, hi = float(a.min()) - self.cell / 2, float(a.max()) + self.cell / 2
        half = self.hull_length(cand) / 2
        clipped = cand.clipped
        if clipped.all() or not clipped.any():  # update() gives no candidate with both
            along = (lo + hi) / 2
        elif clipped[1]:  # the high end may be cut off: the low end is the hull's end
            along = lo + half
        else:
            along = hi - half
        learned = not np.isnan(cand.learned_length)
        along_std = self.end_std if learned or not clipped.any() else self.length_std
        centre = cand.centroid + along * u + across * n
        basis = np.column_stack([u, n])
        cov = (basis * np.array([along_std**2, self.beam_std**2])) @ basis.T
        return centre, cov


def _hull_axis(cells: np.ndarray, d0: float = 0.05) -> np.ndarray:
    """Unit vector (2,) along the long side of the rectangle that fits `cells` (k, 2) m best
    by the closeness criterion of L-shape fitting (Zhang et al., "Efficient L-shape fitting
    for vehicle detection using laser scanners", IEEE IV 2017): over headings in 1° steps,
    every cell scores 1 / max(d, d0), d its distance to the nearest side of the heading's
    bounding rectangle. A hull's seen outline is a side or an L (side and bow), where the
    principal axis tilts toward the short leg and the minimum-area rectangle is ambiguous."""
    theta = np.radians(np.arange(0.0, 90.0, 1.0))
    e1 = np.stack([np.cos(theta), np.sin(theta)])  # (2, m)
    e2 = np.stack([-np.sin(theta), np.cos(theta)])
    c1, c2 = cells @ e1, cells @ e2  # (k, m)
    d1 = np.minimum(c1 - c1.min(axis=0), c1.max(axis=0) - c1)
    d2 = np.minimum(c2 - c2.min(axis=0), c2.max(axis=0) - c2)
    score = (1.0 / np.maximum(np.minimum(d1, d2), d0)).sum(axis=0)
    best = int(np.argmax(score))
    ext1 = float(c1[:, best].max() - c1[:, best].min())
    ext2 = float(c2[:, best].max() - c2[:, best].min())
    return e1[:, best].copy() if ext1 >= ext2 else e2[:, best].copy()


def single_linkage(points: np.ndarray, link: float) -> np.ndarray:
    """Group label (n,) int64 of every point of `points` (n, 2) m: the connected components
    of the graph joining points at most `link` m apart (DBSCAN with one sample per core;
    SciPy's KDTree and csgraph)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    from scipy.spatial import KDTree

    pts = as_float_array("points", points, ndim=2).reshape(-1, 2)
    link = real("link", link, low=0.0)
    if len(pts) == 0:
        return np.zeros(0, dtype=np.int64)
    pairs = KDTree(pts).query_pairs(link, output_type="ndarray")
    graph = coo_matrix(
        (np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(len(pts), len(pts))
    )
    return connected_components(graph, directed=False)[1].astype(np.int64)
