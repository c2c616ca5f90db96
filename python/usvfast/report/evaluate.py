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
- "detectors": Table 6.1 scores per sensor and object, and their totals;
- "walls": tracks whose median position lies within `wall_distance` m of a harbour wall or
  inside a pier polygon (needs the scene).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from matplotlib.path import Path as MplPath

from usvfast.metrics import (
    EXCLUDED_KINDS,
    FrameSequence,
    detector_scores,
    gospa_metrics,
    hota_metrics,
    in_range,
    mot_metrics,
    thesis_metrics,
    truth_at,
)
from usvfast.metrics.tables import Detections, Innovations, Nav, Tracks, Truth


def _frame_rows(times: np.ndarray, ids: np.ndarray, t0: float, period: float) -> np.ndarray:
    """Indices of the rows nearest to each frame time, one per (frame, id), within period/2."""
    k = np.rint((times - t0) / period).astype(np.int64)
    off = np.abs(times - (t0 + k * period))
    ok = off <= period / 2 + 1e-9
    idx = np.flatnonzero(ok)
    order = np.lexsort((off[idx], ids[idx], k[idx]))
    idx = idx[order]
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


def tracks_on_walls(tracks: Tracks, walls: list[Any], wall_distance: float) -> list[int]:
    """Ids of the tracks whose median position (NED) is within `wall_distance` m of a wall
    polyline or inside a closed wall polygon (≥ 3 vertices, first = last or implied)."""
    if not walls or len(tracks.time) == 0:
        return []
    ids = np.unique(tracks.track_id)
    med = np.array([np.median(tracks.positions[tracks.track_id == i], axis=0) for i in ids])
    near = np.zeros(len(ids), bool)
    for w in walls:
        poly = np.asarray(w, float).reshape(-1, 2)
        if len(poly) >= 2:
            near |= _segment_distance(med, poly) <= wall_distance
        if len(poly) >= 3:
            near |= MplPath(np.vstack([poly, poly[:1]])).contains_points(med)
    return [int(i) for i in ids[near]]


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
    wall_distance: float = 2.0,
    confidence: float = 0.95,
) -> dict[str, Any]:
    """All metrics of a run (module doc). max_range: metres from the USV within which an
    object is visible (all visible without `nav`); window, cap, min_visible: the thesis's
    protocol (s, m, s); frame_period: seconds between the multi-target frames;
    detector_gate: metres for the Table 6.1 scores; confidence: of the χ² bands."""
    visible = None if nav is None else in_range(truth, nav, max_range)
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
            "min_visible_s": min_visible,
            "frame_period_s": frame_period,
            "hota_zero_distance_m": hota_zero_distance,
            "confidence": confidence,
            "excluded_kinds": list(EXCLUDED_KINDS),
        },
        "thesis": th.as_dict(),
    }
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
            scores = detector_scores(
                truth,
                detections,
                sensor=sensor,
                period=period,
                gate=detector_gate,
                visible=visible,
            )
            tp = sum(s.tp for s in scores)
            frames = sum(s.frames for s in scores)
            det[sensor] = {
                "frame_period_s": period,
                "tp": tp,
                "fn": sum(s.fn for s in scores),
                "cn_max": max((s.cn for s in scores), default=0),
                "tp_rate": tp / frames if frames else float("nan"),
                "objects": [s.as_dict() for s in scores],
            }
        out["detectors"] = det
    if scene is not None:
        out["walls"] = {
            "distance_m": wall_distance,
            "tracks_on_walls": tracks_on_walls(tracks, scene.get("walls", []), wall_distance),
        }
    return out
