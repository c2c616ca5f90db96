"""Reports of a pipeline run: metrics against a ground truth, a printed table, and pictures.

`write_report(out_dir, truth=..., scene=..., origin=...)` reads the files a run wrote into
`out_dir` (tracks.csv, and when present detections.csv, nav.csv, innovations.csv,
camera_frames/) and writes

- `metrics.json` (with a truth; `usvfast.report.evaluate.evaluate_run`),
- `map.png` (harbour, USV path, detections by sensor, truth, tracks with 2σ ellipses; north
  up, metres), `nis.png` (NIS/ANIS with the χ² band, the thesis's Fig. 6.5), `errors.png`
  (per-object position error and NEES over time, with a truth),
- with a visibility.csv beside the truth (simulated recordings), metrics.json's
  "detectable" and its printed rows: the targets some sensor physically saw within its
  coverage for >= 5 s, beside the targets by range and field of view;
- `map.html` with `html=True` (the map, interactive; plotly, the `report` extra),
- `animation.gif` (the global tracking animation with the camera image inset; by default
  when the run wrote camera_frames/).

Example::

    from usvfast.report import write_report
    metrics = write_report("out", truth="sim/truth.csv", scene="sim/scene.json")
    metrics["thesis"]["rmse"]
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from rich.console import Console

from usvfast.metrics.tables import (
    read_detections,
    read_innovations,
    read_nav,
    read_tracks,
    read_truth,
)
from usvfast.report.detectable import DetectableRule, read_visibility
from usvfast.report.evaluate import evaluate_run
from usvfast.report.table import print_summary, summary_tables

__all__ = [
    "DetectableRule",
    "evaluate_run",
    "print_summary",
    "read_visibility",
    "summary_tables",
    "write_report",
]


def _clean(v: Any) -> Any:
    """NaN/inf to None, numpy scalars to Python, recursively (strict JSON)."""
    if isinstance(v, dict):
        return {str(k): _clean(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_clean(x) for x in v]
    if hasattr(v, "item") and not isinstance(v, (str, bytes)):
        v = v.item()
    if isinstance(v, float) and not math.isfinite(v):
        return None
    return v


def _load_scene(scene: Any) -> dict[str, Any] | None:
    if scene is None:
        return None
    if isinstance(scene, dict):
        return scene
    p = Path(scene)
    if not p.is_file():
        raise FileNotFoundError(f"scene: no such file {p}")
    try:
        data = json.loads(p.read_text())
    except json.JSONDecodeError as exc:
        raise ValueError(f"scene: {p} is not valid JSON ({exc})") from exc
    if not isinstance(data, dict):
        raise ValueError(f"scene: {p} must hold a JSON object")
    return data


def _origin(origin: Any, truth: Any) -> tuple[float, float, float] | None:
    if origin is not None:
        try:
            o = tuple(float(x) for x in origin)
        except (TypeError, ValueError) as exc:
            raise TypeError(f"origin: expected (lat, lon, height), got {origin!r}") from exc
        if len(o) != 3:
            raise ValueError(f"origin: expected (lat, lon, height), got {origin!r}")
        return o  # type: ignore[return-value]
    if truth is not None:
        p = Path(truth).with_name("origin.json")
        if p.is_file():
            d = json.loads(p.read_text())
            return (float(d["lat"]), float(d["lon"]), float(d.get("height", 0.0)))
    return None


def write_report(
    out_dir: str | Path,
    truth: str | Path | None = None,
    scene: str | Path | dict[str, Any] | None = None,
    origin: tuple[float, float, float] | None = None,
    *,
    animation: bool | None = None,
    html: bool = False,
    print_table: bool = True,
    console: Console | None = None,
    visibility: str | Path | None = None,
    **metric_options: Any,
) -> dict[str, Any]:
    """Write the report of the run in `out_dir` (module doc) and return the metrics dict
    (empty without `truth`).

    truth: path of a truth.csv (columns time,object_id,kind,north,east). scene: scene.json
    path or its dict (walls, moored boats). origin: (lat deg, lon deg, height m) of the NED
    frame, shown on the map (default: origin.json beside the truth). animation: write
    animation.gif. visibility: a visibility.csv (what each sensor physically saw; default:
    visibility.csv beside the truth when there is one) for the detectable-target rule
    (`usvfast.report.detectable`). metric_options: keywords of `evaluate_run` (max_range,
    cap, ...); with neither `coverage` nor `max_range` given, the sensors' coverage that
    `usvfast run` wrote into summary.json counts (when the run folder has one). Raises
    FileNotFoundError naming a missing tracks.csv, truth, scene or visibility file."""
    out = Path(out_dir)
    if not (out / "tracks.csv").is_file():
        raise FileNotFoundError(f"out_dir: no tracks.csv in {out}")
    if not {"coverage", "max_range"} & metric_options.keys():
        metric_options["coverage"] = _run_coverage(out)
    tracks = read_tracks(out / "tracks.csv")
    det = read_detections(out / "detections.csv") if (out / "detections.csv").is_file() else None
    nav = read_nav(out / "nav.csv") if (out / "nav.csv").is_file() else None
    inn_path = out / "innovations.csv"
    inn = read_innovations(inn_path) if inn_path.is_file() else None
    if truth is not None and not Path(truth).is_file():
        raise FileNotFoundError(f"truth: no such file {truth}")
    gt = read_truth(truth) if truth is not None else None
    sc = _load_scene(scene)
    org = _origin(origin, truth)
    if visibility is None and truth is not None:
        beside = Path(truth).with_name("visibility.csv")
        visibility = beside if beside.is_file() else None
    vis = read_visibility(visibility) if visibility is not None else None
    metrics: dict[str, Any] = {}
    if gt is not None:
        metrics = evaluate_run(
            gt,
            tracks,
            detections=det,
            nav=nav,
            innovations=inn,
            scene=sc,
            visibility=vis,
            **metric_options,
        )
        tables = {
            "truth": gt,
            "tracks": tracks,
            "detections": det,
            "nav": nav,
            "innovations": inn,
            "visibility": vis,
        }
        metrics["inputs"] = {
            name: {"rows": len(t.time), "skipped_lines": t.skipped}
            for name, t in tables.items()
            if t is not None
        }
        metrics = _clean(metrics)
        (out / "metrics.json").write_text(json.dumps(metrics, indent=2))
    _figures(out, tracks, det, nav, inn, gt, sc, org, metrics, animation, html, metric_options)
    if print_table and metrics:
        print_summary(metrics, console)
    return metrics


def _run_coverage(out: Path) -> dict[str, tuple[float, ...]] | None:
    """The sensors' coverage that `usvfast run` wrote into OUT/summary.json, else None."""
    path = out / "summary.json"
    if not path.is_file():
        return None
    try:
        cov = json.loads(path.read_text()).get("coverage")
    except (json.JSONDecodeError, AttributeError) as exc:
        raise ValueError(f"out_dir: {path} is not a summary.json: {exc}") from None
    return {str(k): tuple(map(float, v)) for k, v in cov.items()} if cov else None


def _figures(out, tracks, det, nav, inn, gt, sc, org, metrics, animation, html, options) -> None:
    from usvfast.metrics.protocol import match_tracks
    from usvfast.report import figures as F
    from usvfast.report.animation import write_animation

    th = metrics.get("thesis", {})
    title = f"usvfast run: {len(set(tracks.track_id.tolist()))} tracks"
    if det is not None:
        title += f", {len(det.time)} detections"
    if th.get("rmse") is not None:
        title += f" — RMSE {th['rmse']:.2f} m, TPD {th['tpd']:.2f}"
    F.save(
        F.map_figure(tracks, detections=det, nav=nav, truth=gt, scene=sc, title=title, origin=org),
        out / "map.png",
    )
    if inn is not None and len(inn.time):
        F.save(F.nis_figure(inn), out / "nis.png")
    if gt is not None:
        cap = float(options.get("cap", 5.0))
        m = match_tracks(gt, tracks, window=float(options.get("window", 1.0)), cap=cap)
        targets = [o["object_id"] for o in th.get("objects", []) if o["target"]]
        names = {i: gt.name(i) for i in gt.kinds()} if gt.names else None
        F.save(F.errors_figure(m, gt.kinds(), targets, cap=cap, names=names), out / "errors.png")
    if html:
        from usvfast.report.interactive import write_html_map

        write_html_map(
            out / "map.html", tracks, detections=det, nav=nav, truth=gt, scene=sc, title=title
        )
    if animation is None:
        animation = (out / "camera_frames" / "camera_frames.csv").is_file()
    if animation:
        write_animation(
            out / "animation.gif",
            tracks,
            detections=det,
            nav=nav,
            truth=gt,
            scene=sc,
            camera_dir=out / "camera_frames",
        )
