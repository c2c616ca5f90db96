"""The thesis's evaluation of a tracker run against a ground truth (§4.3.2 with the matching
protocol of §7.3.1).

Matching (§7.3.1): every track row is compared with every truth object at the row's time — the
truth linearly interpolated between its samples, which must lie within ±`window` s (1 s) — and
the pair is a candidate when each position component differs by at most `cap` m (5 m). At each
track update time the candidates are matched one to one (most pairs, then least total
distance).

Per object (a "target": every truth object whose kind is not excluded, e.g. moored boats, and
that is visible for at least `min_visible` s):

- RMSE (eq. 4.4): √(mean |x̂ − x|²) over its matched rows, metres;
- NEES (eq. 4.5) of the matched rows with the track's position covariance (2 dof) and ANEES
  with its χ² band;
- TPD: the fraction of its visible time covered by matched track segments; the run's TPD is
  the thesis's "tracked targets divided by total number of targets";
- TT: the duration of its longest matched segment of one track (s);
- TRF: the number of distinct tracks matched to it ("tracks necessary to track a single
  target").

ANIS (eq. 4.6) comes from the innovations the tracker logged. Tracks never matched to any
object are false tracks; tracks matched mostly to an excluded kind (moored boats) are listed
apart. Example::

    m = thesis_metrics(read_truth("truth.csv"), read_tracks("tracks.csv"),
                       innovations=read_innovations("innovations.csv"))
    m.tpd, m.rmse, m.anees.inside, [o.trf for o in m.objects]
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from usvfast._core import DimensionError
from usvfast._validate import instance
from usvfast.metrics.consistency import Consistency, average_consistency, nees
from usvfast.metrics.mot import _gated_assignment
from usvfast.metrics.tables import Innovations, Nav, Tracks, Truth

#: Kinds of truth objects that are not targets (tracks on them are reported apart).
EXCLUDED_KINDS = ("moored_boat",)


@dataclass(frozen=True)
class Matches:
    """Track rows matched to truth objects (§7.3.1): row (M,) index into the tracks table,
    time (M,) s, track_id (M,), object_id (M,), truth (M, 2) the truth position at the row's
    time, error (M, 2) track − truth (NED m), nees (M,) with the row's position covariance
    (NaN when it has none or it is not positive definite)."""

    row: np.ndarray
    time: np.ndarray
    track_id: np.ndarray
    object_id: np.ndarray
    truth: np.ndarray
    error: np.ndarray
    nees: np.ndarray


def truth_at(truth: Truth, object_id: int, times: ArrayLike, window: float = 1.0) -> np.ndarray:
    """Position (n, 2) of one object at `times` (n,) s: linear interpolation between its
    samples when both neighbours lie within `window` s, else its nearest sample within
    `window`, else NaN."""
    instance("truth", truth, Truth)
    t = np.asarray(times, float)
    sel = truth.object_id == object_id
    order = np.argsort(truth.time[sel], kind="stable")
    ts, ps = truth.time[sel][order], truth.positions[sel][order]
    out = np.full((len(t), 2), np.nan)
    if len(ts) == 0:
        return out
    i = np.clip(np.searchsorted(ts, t), 1, max(len(ts) - 1, 1))
    lo, hi = np.maximum(i - 1, 0), np.minimum(i, len(ts) - 1)
    d_lo, d_hi = np.abs(t - ts[lo]), np.abs(ts[hi] - t)
    both = (d_lo <= window) & (d_hi <= window) & (ts[lo] <= t) & (t <= ts[hi])
    span = np.where(ts[hi] > ts[lo], ts[hi] - ts[lo], 1.0)
    w = np.clip((t - ts[lo]) / span, 0.0, 1.0)[:, None]
    interp = ps[lo] * (1 - w) + ps[hi] * w
    near = np.where((d_lo <= d_hi)[:, None], ps[lo], ps[hi])
    near_ok = np.minimum(d_lo, d_hi) <= window
    out[near_ok] = near[near_ok]
    out[both] = interp[both]
    return out


def _row_nees(errors: np.ndarray, cov: np.ndarray) -> np.ndarray:
    out = np.full(len(errors), np.nan)
    ok = np.all(np.isfinite(cov.reshape(len(cov), 4)), axis=1)
    if ok.any():
        sym = 0.5 * (cov[ok] + np.swapaxes(cov[ok], 1, 2))
        pd = np.linalg.eigvalsh(sym)[:, 0] > 0
        idx = np.flatnonzero(ok)[pd]
        out[idx] = nees(errors[idx], sym[pd])
    return out


def match_tracks(truth: Truth, tracks: Tracks, *, window: float = 1.0, cap: float = 5.0) -> Matches:
    """Match track rows to truth objects with the thesis's protocol (module doc). window:
    seconds; cap: metres per component. Raises ValueError on a non-positive window or cap."""
    instance("truth", truth, Truth)
    instance("tracks", tracks, Tracks)
    if not window > 0:
        raise ValueError(f"window: must be positive, got {window}")
    if not cap > 0:
        raise ValueError(f"cap: must be positive, got {cap}")
    objects = np.unique(truth.object_id)
    n = len(tracks.time)
    if n == 0 or len(objects) == 0:
        z = np.zeros(0, np.int64)
        return Matches(z, np.zeros(0), z, z, np.zeros((0, 2)), np.zeros((0, 2)), np.zeros(0))
    cost = np.full((n, len(objects)), np.nan)
    truth_pos = np.full((n, len(objects), 2), np.nan)
    for j, o in enumerate(objects):
        at = truth_at(truth, int(o), tracks.time, window)
        diff = tracks.positions - at
        ok = np.all(np.abs(diff) <= cap, axis=1)  # NaN compares False
        cost[ok, j] = np.hypot(diff[ok, 0], diff[ok, 1])
        truth_pos[:, j] = at
    cand = np.isfinite(cost)
    times, t_idx = np.unique(tracks.time, return_inverse=True)
    per_row = cand.sum(1)
    per_time_obj = np.zeros((len(times), len(objects)), np.int64)
    r_c, o_c = np.nonzero(cand)
    np.add.at(per_time_obj, (t_idx[r_c], o_c), 1)
    # Rows with a single candidate that no other row of their time shares: matched directly.
    single = per_row == 1
    obj_single = np.argmax(cand, axis=1)
    simple = single & (per_time_obj[t_idx, obj_single] == 1)
    rows = [np.flatnonzero(simple)]
    objs = [obj_single[simple]]
    # The other times: one-to-one assignment among their rows.
    conflict = np.unique(t_idx[(per_row > 0) & ~simple])
    for k in conflict:
        at_k = np.flatnonzero(t_idx == k)
        r, c = _gated_assignment(cost[at_k])
        rows.append(at_k[r])
        objs.append(c)
    row = np.concatenate(rows).astype(np.int64)
    obj = np.concatenate(objs).astype(np.int64)
    order = np.lexsort((row, tracks.time[row]))
    row, obj = row[order], obj[order]
    tp = truth_pos[row, obj]
    err = tracks.positions[row] - tp
    return Matches(
        row=row,
        time=tracks.time[row],
        track_id=tracks.track_id[row],
        object_id=objects[obj],
        truth=tp,
        error=err,
        nees=_row_nees(err, tracks.covariances[row]),
    )


def in_range(
    truth: Truth, nav: Nav, max_range: float, fov_deg: float = 360.0, yaw_deg: float = 0.0
) -> np.ndarray:
    """(N,) mask of the truth rows within `max_range` m of the USV and, with `fov_deg` < 360,
    within ±fov_deg/2 of the sensor's axis (the USV heading + `yaw_deg`, clockwise). The USV
    position and heading are linearly interpolated at the truth time; rows outside the pose
    times are out of range."""
    if not max_range > 0:
        raise ValueError(f"max_range: must be positive, got {max_range}")
    instance("truth", truth, Truth)
    instance("nav", nav, Nav)
    if not 0 < fov_deg <= 360:
        raise ValueError(f"fov_deg: must lie in (0, 360], got {fov_deg}")
    if len(nav.time) == 0:
        return np.zeros(len(truth.time), bool)
    order = np.argsort(nav.time, kind="stable")
    t, p = nav.time[order], nav.positions[order]
    usv = np.column_stack([np.interp(truth.time, t, p[:, 0]), np.interp(truth.time, t, p[:, 1])])
    inside = (truth.time >= t[0]) & (truth.time <= t[-1])
    rel = truth.positions - usv
    ok = inside & (np.linalg.norm(rel, axis=1) <= max_range)
    if fov_deg < 360:
        heading = np.interp(truth.time, t, np.unwrap(np.radians(nav.heading_deg[order])))
        bearing = np.arctan2(rel[:, 1], rel[:, 0])  # clockwise from north
        off = np.angle(np.exp(1j * (bearing - heading - np.radians(yaw_deg))))
        ok &= np.abs(off) <= np.radians(fov_deg) / 2
    return ok


def _intervals(times: np.ndarray, max_gap: float) -> np.ndarray:
    """(k, 2) [start, end] of the runs of sorted `times` without a gap above max_gap."""
    if len(times) == 0:
        return np.zeros((0, 2))
    cut = np.flatnonzero(np.diff(times) > max_gap)
    starts = np.r_[0, cut + 1]
    ends = np.r_[cut, len(times) - 1]
    return np.column_stack([times[starts], times[ends]])


def _union(iv: np.ndarray) -> np.ndarray:
    if len(iv) == 0:
        return iv
    iv = iv[np.argsort(iv[:, 0])]
    # a new run starts where the start lies beyond every earlier end
    ends = np.maximum.accumulate(iv[:, 1])
    new = np.r_[True, iv[1:, 0] > ends[:-1]]
    grp = np.cumsum(new) - 1
    out = np.zeros((grp[-1] + 1, 2))
    out[:, 0] = iv[new, 0]
    np.maximum.at(out[:, 1], grp, iv[:, 1])
    return out


def _overlap(a: np.ndarray, b: np.ndarray) -> float:
    """Total length of the intersection of two unions of disjoint intervals."""
    if len(a) == 0 or len(b) == 0:
        return 0.0
    lo = np.maximum(a[:, None, 0], b[None, :, 0])
    hi = np.minimum(a[:, None, 1], b[None, :, 1])
    return float(np.clip(hi - lo, 0.0, None).sum())


@dataclass(frozen=True)
class ObjectScore:
    """Figures of one truth object (module doc): name its id in the truth file,
    visible_time and tracked_time in seconds, tpd = tracked_time / visible_time, tt seconds,
    trf tracks, rmse metres (NaN when never matched), anees its ANEES (None without
    covariances), track_ids the matched tracks, target: whether it counts in the run's
    figures."""

    object_id: int
    name: str
    kind: str
    target: bool
    visible_time: float
    tracked_time: float
    tpd: float
    tt: float
    trf: int
    rmse: float
    n_matches: int
    anees: Consistency | None
    track_ids: list[int] = field(default_factory=list)

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready dict."""
        d = {k: getattr(self, k) for k in self.__dataclass_fields__ if k != "anees"}
        d["anees"] = self.anees.as_dict() if self.anees else None
        return d


@dataclass(frozen=True)
class ThesisMetrics:
    """The run's figures (module doc): tpd = targets_tracked / n_targets; mean_tpd the mean of
    the targets' time fractions; mean_trf over tracked targets; rmse metres over every matched
    row of a target; anees / anis with their χ² bands (None without data); anis_by_sensor;
    false_tracks: ids never matched; excluded_tracks: ids matched mostly to an excluded kind,
    by kind; n_tracks: distinct track ids; by_kind: targets, tracked, mean TPD and RMSE per
    target kind."""

    objects: list[ObjectScore]
    n_targets: int
    targets_tracked: int
    tpd: float
    mean_tpd: float
    mean_trf: float
    max_trf: int
    rmse: float
    anees: Consistency | None
    anis: Consistency | None
    anis_by_sensor: dict[str, Consistency | None]
    false_tracks: list[int]
    excluded_tracks: dict[str, list[int]]
    n_tracks: int
    matches: Matches
    by_kind: dict[str, dict[str, Any]] = field(default_factory=dict)

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready dict (without the per-row matches)."""
        return {
            "n_targets": self.n_targets,
            "targets_tracked": self.targets_tracked,
            "tpd": self.tpd,
            "mean_tpd": self.mean_tpd,
            "mean_trf": self.mean_trf,
            "max_trf": self.max_trf,
            "rmse": self.rmse,
            "anees": self.anees.as_dict() if self.anees else None,
            "anis": self.anis.as_dict() if self.anis else None,
            "anis_by_sensor": {
                k: v.as_dict() if v else None for k, v in self.anis_by_sensor.items()
            },
            "false_tracks": self.false_tracks,
            "excluded_tracks": self.excluded_tracks,
            "n_tracks": self.n_tracks,
            "by_kind": self.by_kind,
            "objects": [o.as_dict() for o in self.objects],
        }


def _by_kind(targets: list[ObjectScore], m: Matches) -> dict[str, dict[str, Any]]:
    """Targets, tracked targets, mean time fraction and RMSE per kind of target."""
    out: dict[str, dict[str, Any]] = {}
    for kind in sorted({o.kind for o in targets}):
        mine = [o for o in targets if o.kind == kind]
        rows = np.isin(m.object_id, [o.object_id for o in mine])
        out[kind] = {
            "n_targets": len(mine),
            "targets_tracked": sum(1 for o in mine if o.n_matches),
            "mean_tpd": float(np.mean([o.tpd for o in mine])),
            "rmse": _rmse(m.error[rows]),
        }
    return out


def _rmse(err: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.sum(err**2, axis=1)))) if len(err) else float("nan")


def matched_anees(matches: Matches, keep: np.ndarray, confidence: float) -> Consistency | None:
    """ANEES (position, 2 dof) of the matched rows `keep` (a mask) and its χ² band, also the
    band corrected for the NEES of each track being correlated in time."""
    rows = np.flatnonzero(keep)
    rows = rows[np.argsort(matches.time[rows], kind="stable")]
    return average_consistency(matches.nees[rows], 2, confidence, groups=matches.track_id[rows])


def thesis_metrics(
    truth: Truth,
    tracks: Tracks,
    *,
    innovations: Innovations | None = None,
    visible: ArrayLike | None = None,
    window: float = 1.0,
    cap: float = 5.0,
    min_visible: float = 5.0,
    exclude_kinds: tuple[str, ...] = EXCLUDED_KINDS,
    confidence: float = 0.95,
) -> ThesisMetrics:
    """RMSE, NEES/ANEES, NIS/ANIS, TPD, TT and TRF of a run (module doc).

    visible: (N,) bool over the truth rows (e.g. `in_range`), default all; min_visible:
    seconds an object must be visible to count as a target; window, cap: the matching
    protocol (s, m); confidence: of the χ² bands. Raises DimensionError when `visible` does not
    match the truth."""
    instance("truth", truth, Truth)
    instance("tracks", tracks, Tracks)
    if innovations is not None:
        instance("innovations", innovations, Innovations)
    vis = np.ones(len(truth.time), bool) if visible is None else np.asarray(visible, bool)
    if vis.shape != truth.time.shape:
        raise DimensionError(f"visible: expected shape {truth.time.shape}, got {vis.shape}")
    m = match_tracks(truth, tracks, window=window, cap=cap)
    kinds = truth.kinds()
    objects: list[ObjectScore] = []
    for oid, kind in kinds.items():
        sel = (truth.object_id == oid) & vis
        vis_iv = _intervals(np.sort(truth.time[sel]), window)
        visible_time = float((vis_iv[:, 1] - vis_iv[:, 0]).sum())
        mine = m.object_id == oid
        segs = []
        for tid in np.unique(m.track_id[mine]):
            segs.append(_intervals(m.time[mine & (m.track_id == tid)], window))
        seg = np.concatenate(segs) if segs else np.zeros((0, 2))
        tracked = _overlap(_union(seg), vis_iv)
        target = kind not in exclude_kinds and visible_time >= min_visible
        good = mine & np.isfinite(m.nees)
        objects.append(
            ObjectScore(
                object_id=oid,
                name=truth.name(oid),
                kind=kind,
                target=bool(target),
                visible_time=visible_time,
                tracked_time=tracked,
                tpd=tracked / visible_time if visible_time > 0 else float("nan"),
                tt=float((seg[:, 1] - seg[:, 0]).max()) if len(seg) else 0.0,
                trf=len(segs),
                rmse=_rmse(m.error[mine]),
                n_matches=int(mine.sum()),
                anees=matched_anees(m, good, confidence),
                track_ids=[int(t) for t in np.unique(m.track_id[mine])],
            )
        )
    targets = [o for o in objects if o.target]
    tracked_t = [o for o in targets if o.n_matches]
    target_ids = np.array([o.object_id for o in targets], np.int64)
    on_target = np.isin(m.object_id, target_ids)
    good = on_target & np.isfinite(m.nees)
    # tracks matched mostly to an excluded kind
    excluded: dict[str, list[int]] = {}
    kind_ids = np.array(list(kinds), np.int64)
    kind_names = np.array(list(kinds.values()), dtype=str)
    kind_of_match = kind_names[np.searchsorted(kind_ids, m.object_id)]
    for tid in np.unique(m.track_id):
        mk = kind_of_match[m.track_id == tid]
        values, counts = np.unique(mk, return_counts=True)
        top = str(values[np.argmax(counts)])
        if top in exclude_kinds:
            excluded.setdefault(top, []).append(int(tid))
    all_tracks = np.unique(tracks.track_id)
    anis: Consistency | None = None
    by_sensor: dict[str, Consistency | None] = {}
    if innovations is not None and len(innovations.nis):
        inn = innovations
        rows = np.argsort(inn.time, kind="stable")  # each track's NIS in time order
        anis = average_consistency(
            inn.nis[rows], inn.dof[rows], confidence, inn.gate_of(rows), inn.track_id[rows]
        )
        for s in np.unique(inn.sensor):
            k = rows[inn.sensor[rows] == s]
            by_sensor[str(s)] = average_consistency(
                inn.nis[k], inn.dof[k], confidence, inn.gate_of(k), inn.track_id[k]
            )
    return ThesisMetrics(
        objects=objects,
        n_targets=len(targets),
        targets_tracked=len(tracked_t),
        tpd=len(tracked_t) / len(targets) if targets else float("nan"),
        mean_tpd=float(np.mean([o.tpd for o in targets])) if targets else float("nan"),
        mean_trf=float(np.mean([o.trf for o in tracked_t])) if tracked_t else float("nan"),
        max_trf=max((o.trf for o in tracked_t), default=0),
        rmse=_rmse(m.error[on_target]),
        anees=matched_anees(m, good, confidence),
        anis=anis,
        anis_by_sensor=by_sensor,
        false_tracks=[int(t) for t in np.setdiff1d(all_tracks, m.track_id)],
        excluded_tracks=excluded,
        n_tracks=len(all_tracks),
        by_kind=_by_kind(targets, m),
        matches=m,
    )
