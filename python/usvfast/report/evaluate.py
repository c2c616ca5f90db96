"""The metrics of a pipeline run against a ground truth, gathered into one JSON-ready dict.

`evaluate_run` reads nothing itself: it takes the tables (`usvfast.metrics.tables`) and
returns `metrics.json`'s content:

- "thesis": the thesis's figures (`usvfast.metrics.thesis_metrics`: TPD, TT, TRF, RMSE,
  ANEES, ANIS, per object), targets being the objects within `max_range` m of the USV for
  at least 5 s;
- "clear_mot", "hota", "gospa": the multi-target scores on frames every `frame_period` s,
  truth objects that are visible targets against every track (a track on a moored boat or
  a wall is a false positive), Euclidean gate `cap` m, HOTA similarity zero at
  `hota_zero_distance` m, GOSPA cut-off `cap` m, p = 2;
- "detectors": Table 6.1 scores per sensor and object, and their totals, over the frames in
  which the object lies within the sensor's range and field of view;
- "walls": tracks whose median position lies within `wall_distance` m of a harbour wall or
  inside a pier polygon, and of a moored boat's outline (needs the scene), that are not an
  object's track (`track_groups`: matched to an object of a kind that is not excluded in most
  of their matched rows): the tracks the walls or the hulls made. An object's track near a
  wall (a vessel passing a pier head) is listed apart ("object_tracks_near_walls",
  "object_tracks_near_moored_boats");
- "groups": the thesis's run figures again for each group of target kinds (`GROUPS`):
  "floats", the floating objects (every kind but the vessels), and "vessels", the boats under
  way (`group_metrics`). "thesis" stays the pooled figure over every target;
- "detectable" (with a visibility file: what each sensor physically saw): the targets by a
  second rule, beside the range rule's (`usvfast.report.detectable`): the range rule's
  targets that a sensor saw (LiDAR returns per rotation, camera box height) while they lay
  within its coverage, for `min_seen_s` in total; pooled and per group, and each object's
  seconds seen.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from matplotlib.path import Path as MplPath

from usvfast._validate import instance
from usvfast.metrics import (
    EXCLUDED_KINDS,
    Consistency,
    FrameSequence,
    ThesisMetrics,
    average_consistency,
    detector_scores,
    gospa_metrics,
    hota_metrics,
    in_range,
    mot_metrics,
    thesis_metrics,
    truth_at,
)
from usvfast.metrics.protocol import matched_anees
from usvfast.metrics.tables import Detections, Innovations, Nav, Tracks, Truth
from usvfast.report.detectable import (
    DetectableRule,
    Visibility,
    detectable_mask,
    seen_seconds,
)

#: Truth kinds of the "vessels" group (boats under way); every other target kind is a
#: floating object ("floats").
VESSEL_KINDS = ("vessel",)
#: The groups of target kinds reported apart: key -> label.
GROUPS = {"floats": "floating objects", "vessels": "vessels"}


def kind_group(kind: str) -> str:
    """The group key (`GROUPS`) of a truth kind: "vessels" for `VESSEL_KINDS`, else "floats"."""
    instance("kind", kind, str)
    return "vessels" if kind in VESSEL_KINDS else "floats"


def _dict(c: Consistency | None) -> dict[str, Any] | None:
    return c.as_dict() if c is not None else None


def _anis(inn: Innovations, keep: np.ndarray, confidence: float) -> dict[str, Any] | None:
    """ANIS and its (gated) band over the rows `keep` of `inn`, also corrected for the
    correlation of each track's NIS, as a dict."""
    rows = np.flatnonzero(keep)
    rows = rows[np.argsort(inn.time[rows], kind="stable")]  # each track's NIS in time order
    return _dict(
        average_consistency(
            inn.nis[rows], inn.dof[rows], confidence, inn.gate_of(rows), inn.track_id[rows]
        )
    )


def track_groups(
    th: ThesisMetrics, exclude_kinds: tuple[str, ...] = EXCLUDED_KINDS
) -> dict[int, str]:
    """Group key of every track matched to a truth object: the group of the kind of the object
    it is matched to in most of its matched rows (ties: the lower object id). Tracks never
    matched, and tracks matched mostly to an excluded kind (moored boats), are in no group."""
    instance("th", th, ThesisMetrics)
    kinds = {o.object_id: o.kind for o in th.objects}
    m = th.matches
    out: dict[int, str] = {}
    for tid in np.unique(m.track_id):
        ids, counts = np.unique(m.object_id[m.track_id == tid], return_counts=True)
        kind = kinds[int(ids[np.argmax(counts)])]
        if kind not in exclude_kinds:
            out[int(tid)] = kind_group(kind)
    return out


def sensor_switch(innovations: Innovations) -> np.ndarray:
    """(N,) bool: the update's sensor differs from that of the same track's previous update
    (False for a track's first). Same-sensor NIS in its band but switch NIS above it is the
    mark of an offset between the sensors that no single R explains (each sensor's errors
    about an object are correlated from update to update; a track follows the last sensor)."""
    instance("innovations", innovations, Innovations)
    order = np.lexsort((innovations.time, innovations.track_id))
    tid, sensor = innovations.track_id[order], innovations.sensor[order]
    changed = np.zeros(len(order), bool)
    changed[1:] = (tid[1:] == tid[:-1]) & (sensor[1:] != sensor[:-1])
    out = np.zeros(len(order), bool)
    out[order] = changed
    return out


def group_metrics(
    th: ThesisMetrics,
    innovations: Innovations | None = None,
    confidence: float = 0.95,
    exclude_kinds: tuple[str, ...] = EXCLUDED_KINDS,
) -> dict[str, dict[str, Any]]:
    """The run's figures per group of target kinds (`GROUPS`), from the pooled `th` of
    `thesis_metrics`: targets (the group's target objects) and how many are tracked, TPD,
    TRF mean / max over the tracked ones, RMSE (m) and ANEES (χ² band) over the matched rows
    of the group's targets, and ANIS (its own χ² band, also per sensor) over the innovations
    of the group's tracks (`track_groups`: a track belongs to the group of the object it is
    matched to most), and split by `sensor_switch`. Every group is listed, empty or not (NaN
    figures, None bands)."""
    instance("th", th, ThesisMetrics)
    if innovations is not None:
        instance("innovations", innovations, Innovations)
    m = th.matches
    by_track = track_groups(th, exclude_kinds)
    out: dict[str, dict[str, Any]] = {}
    for key, label in GROUPS.items():
        targets = [o for o in th.objects if o.target and kind_group(o.kind) == key]
        tracked = [o for o in targets if o.n_matches]
        rows = np.isin(m.object_id, [o.object_id for o in targets])
        good = rows & np.isfinite(m.nees)
        err = m.error[rows]
        g: dict[str, Any] = {
            "label": label,
            "n_targets": len(targets),
            "targets_tracked": len(tracked),
            "tpd": len(tracked) / len(targets) if targets else float("nan"),
            "mean_trf": float(np.mean([o.trf for o in tracked])) if tracked else float("nan"),
            "max_trf": max((o.trf for o in tracked), default=0),
            "rmse": float(np.sqrt(np.mean(np.sum(err**2, axis=1)))) if len(err) else float("nan"),
            "anees": _dict(matched_anees(m, good, confidence)),
            "tracks": sorted(t for t, k in by_track.items() if k == key),
            "anis": None,
            "anis_by_sensor": {},
            "anis_by_switch": {},
        }
        if innovations is not None and len(innovations.nis):
            inn = innovations
            mine = np.isin(inn.track_id, g["tracks"])
            g["anis"] = _anis(inn, mine, confidence)
            for s in np.unique(inn.sensor[mine]):
                g["anis_by_sensor"][str(s)] = _anis(inn, mine & (inn.sensor == s), confidence)
            switch = sensor_switch(inn)
            g["anis_by_switch"] = {
                "same_sensor": _anis(inn, mine & ~switch, confidence),
                "sensor_switch": _anis(inn, mine & switch, confidence),
            }
        out[key] = g
    return out


def _frame_rows(times: np.ndarray, ids: np.ndarray, t0: float, period: float) -> np.ndarray:
    """Indices of the rows nearest to each frame time, one per (frame, id), within period/2."""
    k = np.rint((times - t0) / period).astype(np.int64)
    off = np.abs(times - (t0 + k * period))
    ok = off <= period / 2 + 1e-9
    idx = np.flatnonzero(ok)
    order = np.lexsort((off[idx], ids[idx], k[idx]))
    idx = idx[order]
    if len(idx) == 0:
        return idx
    first = np.r_[True, (k[idx][1:] != k[idx][:-1]) | (ids[idx][1:] != ids[idx][:-1])]
    return idx[first]


def frame_sequence(
    truth: Truth,
    tracks: Tracks,
    targets: list[int],
    visible: np.ndarray,
    *,
    t_span: tuple[float, float],
    frame_period: float,
    cap: float,
    zero_distance: float,
) -> FrameSequence:
    """World-frame `FrameSequence` on a grid of `frame_period` s over `t_span`: the target
    objects' truth (interpolated; only where visible) against every track row nearest to each
    frame time."""
    t0, t1 = t_span
    n = int(np.floor((t1 - t0) / frame_period + 1e-9)) + 1
    grid = t0 + frame_period * np.arange(max(n, 0))
    gf, gi, gp = [], [], []
    for oid in targets:
        pos = truth_at(truth, oid, grid, window=frame_period)
        sel = truth.object_id == oid
        ts, vs = truth.time[sel], visible[sel].astype(float)
        order = np.argsort(ts, kind="stable")
        vis = np.interp(grid, ts[order], vs[order]) >= 0.5
        ok = np.all(np.isfinite(pos), axis=1) & vis
        gf.append(np.flatnonzero(ok))
        gi.append(np.full(ok.sum(), oid, np.int64))
        gp.append(pos[ok])
    rows = _frame_rows(tracks.time, tracks.track_id, t0, frame_period)
    k = np.rint((tracks.time[rows] - t0) / frame_period).astype(np.int64)
    keep = (k >= 0) & (k < len(grid))
    rows, k = rows[keep], k[keep]
    return FrameSequence.from_positions(
        np.concatenate([np.zeros(0, np.int64), *gf]),
        np.concatenate([np.zeros(0, np.int64), *gi]),
        np.concatenate([np.zeros((0, 2)), *gp]),
        k,
        tracks.track_id[rows],
        tracks.positions[rows],
        max_distance=cap,
        zero_distance=zero_distance,
        frames=np.arange(len(grid)),
    )


def _segment_distance(points: np.ndarray, line: np.ndarray) -> np.ndarray:
    """Distance (n,) of every point to a polyline (m, 2)."""
    a, b = line[:-1], line[1:]
    ab = b - a
    ap = points[:, None, :] - a[None]
    t = np.clip((ap * ab).sum(-1) / np.maximum((ab**2).sum(-1), 1e-12), 0, 1)
    d = np.linalg.norm(ap - t[..., None] * ab[None], axis=-1)
    return d.min(axis=1)


def is_closed(poly: np.ndarray) -> bool:
    """Whether a wall outline (k, 2) is a polygon: ≥ 4 vertices, the last equal to the first
    (scene.json walls are polylines otherwise, e.g. a quay edge)."""
    return len(poly) >= 4 and bool(np.allclose(poly[0], poly[-1]))


def moored_outline(boat: dict[str, Any]) -> np.ndarray:
    """Corners (4, 2) NED m of a moored boat of scene.json (centre north/east, `length` along
    `heading_deg` clockwise from north, `width`)."""
    h = np.radians(float(boat.get("heading_deg", 0.0)))
    fwd = np.array([np.cos(h), np.sin(h)])
    side = np.array([-np.sin(h), np.cos(h)])
    c = np.array([float(boat["north"]), float(boat["east"])])
    hl, hw = float(boat.get("length", 6.0)) / 2, float(boat.get("width", 2.5)) / 2
    return np.array(
        [c + a * hl * fwd + b * hw * side for a, b in ((1, 1), (1, -1), (-1, -1), (-1, 1))]
    )


def tracks_on_walls(
    tracks: Tracks, walls: list[Any], wall_distance: float, *, closed: bool = False
) -> list[int]:
    """Ids of the tracks whose median position (NED) is within `wall_distance` m of a wall
    polyline or inside a closed wall polygon (≥ 4 vertices with the first repeated last);
    `closed=True` closes every outline (moored boats)."""
    if not walls or len(tracks.time) == 0:
        return []
    ids = np.unique(tracks.track_id)
    med = np.array([np.median(tracks.positions[tracks.track_id == i], axis=0) for i in ids])
    near = np.zeros(len(ids), bool)
    for w in walls:
        poly = np.asarray(w, float).reshape(-1, 2)
        if len(poly) >= 2:
            near |= _segment_distance(med, poly) <= wall_distance
        if is_closed(poly) or (closed and len(poly) >= 3):
            near |= MplPath(np.vstack([poly, poly[:1]])).contains_points(med)
    return [int(i) for i in ids[near]]


_SUMMARY_KEYS = ("n_targets", "targets_tracked", "tpd", "mean_trf", "max_trf", "rmse")


def _detectable(
    truth: Truth,
    tracks: Tracks,
    nav: Nav,
    innovations: Innovations | None,
    visibility: Visibility,
    rule: DetectableRule | None,
    coverage: dict[str, tuple[float, float, float]] | None,
    max_range: float,
    visible: np.ndarray,
    protocol: dict[str, Any],
) -> dict[str, Any]:
    """metrics.json's "detectable": the rule; every object's seconds seen by a sensor within
    its coverage (`seen_seconds`) and whether it is a detectable target (a target of the
    range rule seen for at least `rule.min_seen_s`); those targets' figures, pooled and per
    group (targets, tracked, TPD, TRF, RMSE over the rows of the range rule). Without
    `coverage` every sensor of the visibility file covers max_range all round."""
    rule = rule or DetectableRule()
    cov = coverage or {s: (max_range, 360.0, 0.0) for s in np.unique(visibility.sensor)}
    seconds = seen_seconds(truth, detectable_mask(truth, nav, cov, visibility, rule))
    ok = [oid for oid, sec in seconds.items() if sec >= rule.min_seen_s - 1e-9]
    mask = visible & np.isin(truth.object_id, ok)
    th = thesis_metrics(truth, tracks, innovations=innovations, visible=mask, **protocol)
    groups = group_metrics(th, innovations, protocol["confidence"])
    return {
        "rule": rule.as_dict(),
        **{k: getattr(th, k) for k in _SUMMARY_KEYS},
        "groups": {k: {f: g[f] for f in ("label", *_SUMMARY_KEYS)} for k, g in groups.items()},
        "objects": [
            {
                "object_id": o.object_id,
                "kind": o.kind,
                "seen_seconds": seconds.get(o.object_id, 0.0),
                "target": o.target,
                "tracked_time": o.tracked_time,
            }
            for o in th.objects
        ],
    }


def _visible(
    truth: Truth,
    nav: Nav,
    max_range: float,
    coverage: dict[str, tuple[float, float, float]] | None,
) -> np.ndarray:
    """(N,) mask of the truth rows within max_range all round or, with `coverage`, within
    any sensor's (range, field of view, yaw)."""
    if not coverage:
        return in_range(truth, nav, max_range)
    if not isinstance(coverage, dict):
        raise TypeError(
            f"coverage: expected a dict of sensor -> (range, fov, yaw), got {coverage!r}"
        )
    out = np.zeros(len(truth.time), bool)
    for name, spec in coverage.items():
        try:
            rng, fov, yaw = (float(v) for v in spec)
        except (TypeError, ValueError):
            raise ValueError(
                f"coverage[{name!r}]: expected (range m, fov deg, yaw deg), got {spec!r}"
            ) from None
        out |= in_range(truth, nav, rng, fov, yaw)
    return out


def evaluate_run(
    truth: Truth,
    tracks: Tracks,
    *,
    detections: Detections | None = None,
    nav: Nav | None = None,
    innovations: Innovations | None = None,
    scene: dict[str, Any] | None = None,
    max_range: float = 40.0,
    window: float = 1.0,
    cap: float = 5.0,
    min_visible: float = 5.0,
    frame_period: float = 0.5,
    hota_zero_distance: float = 2.0,
    detector_gate: float = 1.0,
    sensor_range: dict[str, float] | None = None,
    sensor_fov_deg: dict[str, float] | None = None,
    wall_distance: float = 2.0,
    confidence: float = 0.95,
    coverage: dict[str, tuple[float, float, float]] | None = None,
    visibility: Visibility | None = None,
    detectable_rule: DetectableRule | None = None,
) -> dict[str, Any]:
    """All metrics of a run (module doc). max_range: metres from the USV within which an
    object is visible (all visible without `nav`); window, cap, min_visible: the thesis's
    protocol (s, m, s); frame_period: seconds between the multi-target frames;
    detector_gate: metres for the Table 6.1 scores; sensor_range / sensor_fov_deg: per sensor
    name, the range (m, default max_range) and horizontal field of view (deg, centred on the
    heading; default 360) within which a detector is scored; confidence: of the χ² bands;
    coverage: per sensor name, (range m, horizontal field of view deg, axis yaw deg clockwise
    from the heading): an object is then visible while it lies within some sensor's coverage
    (instead of within max_range all round), and each detector is scored within its own
    (unless sensor_range / sensor_fov_deg say otherwise). visibility (with nav): what each
    sensor physically saw (`usvfast.report.detectable.read_visibility`); the result then
    also holds "detectable": the targets by the detectable rule (`detectable_rule`, default
    `DetectableRule()`), beside the range rule's."""
    visible = None if nav is None else _visible(truth, nav, max_range, coverage)
    th = thesis_metrics(
        truth,
        tracks,
        innovations=innovations,
        visible=visible,
        window=window,
        cap=cap,
        min_visible=min_visible,
        confidence=confidence,
    )
    vis = np.ones(len(truth.time), bool) if visible is None else visible
    targets = [o.object_id for o in th.objects if o.target]
    spans = [tracks.time, truth.time[vis]] if nav is None else [nav.time]
    allt = np.concatenate([np.zeros(0), *spans])
    out: dict[str, Any] = {
        "protocol": {
            "window_s": window,
            "cap_m": cap,
            "max_range_m": max_range if nav is not None else None,
            "coverage": {k: list(v) for k, v in (coverage or {}).items()} or None,
            "min_visible_s": min_visible,
            "frame_period_s": frame_period,
            "hota_zero_distance_m": hota_zero_distance,
            "confidence": confidence,
            "excluded_kinds": list(EXCLUDED_KINDS),
            "groups": {"vessels": list(VESSEL_KINDS), "floats": "every other target kind"},
        },
        "thesis": th.as_dict(),
        "groups": group_metrics(th, innovations, confidence),
    }
    if visibility is not None and nav is not None:
        vis_range = np.ones(len(truth.time), bool) if visible is None else visible
        out["detectable"] = _detectable(
            truth,
            tracks,
            nav,
            innovations,
            visibility,
            detectable_rule,
            coverage,
            max_range,
            vis_range,
            dict(window=window, cap=cap, min_visible=min_visible, confidence=confidence),
        )
    if len(allt):
        seq = frame_sequence(
            truth,
            tracks,
            targets,
            vis,
            t_span=(float(allt.min()), float(allt.max())),
            frame_period=frame_period,
            cap=cap,
            zero_distance=hota_zero_distance,
        )
        out["clear_mot"] = mot_metrics(seq).as_dict()
        out["hota"] = hota_metrics(seq).as_dict()
        out["gospa"] = gospa_metrics(seq, cutoff=cap, order=2).as_dict()
    if detections is not None:
        det: dict[str, Any] = {}
        for sensor in sorted(set(detections.sensor.tolist())):
            period = 0.1
            t = np.unique(detections.time[detections.sensor == sensor])
            if len(t) > 1:
                period = float(np.median(np.diff(t)))
            own = (coverage or {}).get(sensor, (max_range, 360.0, 0.0))
            rng = (sensor_range or {}).get(sensor, own[0])
            fov = (sensor_fov_deg or {}).get(sensor, own[1])
            seen = None if nav is None else in_range(truth, nav, rng, fov, own[2])
            scores = detector_scores(
                truth,
                detections,
                sensor=sensor,
                period=period,
                gate=detector_gate,
                visible=seen,
            )
            tp = sum(s.tp for s in scores)
            frames = sum(s.frames for s in scores)
            det[sensor] = {
                "frame_period_s": period,
                "range_m": rng if nav is not None else None,
                "fov_deg": fov,
                "tp": tp,
                "fn": sum(s.fn for s in scores),
                "cn_max": max((s.cn for s in scores), default=0),
                "tp_rate": tp / frames if frames else float("nan"),
                "objects": [s.as_dict() for s in scores],
            }
        out["detectors"] = det
    if scene is not None:
        boats = [moored_outline(b) for b in scene.get("moored", [])]
        near_walls = tracks_on_walls(tracks, scene.get("walls", []), wall_distance)
        near_boats = tracks_on_walls(tracks, boats, wall_distance, closed=True)
        of_objects = track_groups(th)
        out["walls"] = {
            "distance_m": wall_distance,
            "tracks_on_walls": [i for i in near_walls if i not in of_objects],
            "tracks_on_moored_boats": [i for i in near_boats if i not in of_objects],
            "object_tracks_near_walls": [i for i in near_walls if i in of_objects],
            "object_tracks_near_moored_boats": [i for i in near_boats if i in of_objects],
        }
    return out
