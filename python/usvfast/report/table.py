"""The printed summary of a run's metrics (rich tables): the run's figures, the figures by
group of targets (every target pooled, the floating objects, the vessels: one row each), then
one row per truth object."""

from __future__ import annotations

import math
from typing import Any

from rich import box
from rich.console import Console
from rich.table import Table

from usvfast._validate import instance


def _f(v: Any, fmt: str = "{:.3f}") -> str:
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return "–"
    return fmt.format(v)


def _band(c: dict[str, Any] | None) -> str:
    if not c:
        return "–"
    mark = "inside" if c["inside"] else "[red]OUTSIDE[/red]"
    gated = f", gated P_G {c['gate']:g}: expected {c['expected']:.3f}" if c.get("gate") else ""
    text = f"{c['mean']:.3f}  [{c['lower']:.3f}, {c['upper']:.3f}] {mark} (n={c['n']}{gated})"
    if c.get("variance_factor") is not None:
        mark = "inside" if c["corrected_inside"] else "[red]OUTSIDE[/red]"
        text += (
            f"; correlated in tracks (× {c['variance_factor']:.2f}): "
            f"[{c['corrected_lower']:.3f}, {c['corrected_upper']:.3f}] {mark}"
        )
    return text


def _short(c: dict[str, Any] | None, fmt: str = "{:.2f}") -> str:
    """ "mean [lower,upper]" of a χ² band, in red when the mean lies outside it."""
    if not c:
        return "–"
    text = f"{fmt.format(c['mean'])} [{fmt.format(c['lower'])},{fmt.format(c['upper'])}]"
    return text if c["inside"] else f"[red]{text}[/red]"


def group_table(metrics: dict[str, Any]) -> Table | None:
    """One row per group of targets: every target pooled (the "thesis" figures), then each
    group of `metrics["groups"]` (`usvfast.report.evaluate.group_metrics`): targets tracked /
    targets, TRF mean / max, RMSE m, ANIS and ANEES with their 95 % χ² bands (red: outside).
    None when the metrics have no groups."""
    instance("metrics", metrics, dict)
    groups = metrics.get("groups")
    if not groups:
        return None
    th = metrics.get("thesis", {})
    t = Table(
        title="By group of targets (RMSE m; ANIS of the group's tracks; 95 % bands, red: out)",
        box=box.SIMPLE_HEAD,
        show_edge=False,
        pad_edge=False,
    )
    for col in ("group", "tracked", "TRF", "RMSE", "ANIS", "ANEES"):
        t.add_column(col, justify="left" if col == "group" else "right", no_wrap=True)
    rows = [("all (pooled)", th)] + [(g.get("label", k), g) for k, g in groups.items()]
    for name, g in rows:
        t.add_row(
            name,
            f"{g.get('targets_tracked', '–')}/{g.get('n_targets', '–')}",
            f"{_f(g.get('mean_trf'), '{:.2f}')}/{g.get('max_trf', '–')}",
            _f(g.get("rmse")),
            _short(g.get("anis")),
            _short(g.get("anees"), "{:.1f}"),
        )
    return t


def _detectable_rows(det: dict[str, Any] | None) -> list[tuple[str, str]]:
    """The printed rows of metrics.json's "detectable" (none without it)."""
    if not det:
        return []
    r = det["rule"]
    rule = (
        f"seen ≥ {r['min_seen_s']:g} s: LiDAR ≥ {r['lidar_min_returns']} returns /"
        f" rotation or camera ≥ {r['camera_min_height_px']:g} px tall"
    )
    rows = [
        (f"detectable targets ({rule})", str(det["n_targets"])),
        ("  of them tracked", str(det["targets_tracked"])),
    ]
    for g in (det.get("groups") or {}).values():
        rows.append(
            (f"  {g['label']}: tracked / targets", f"{g['targets_tracked']} / {g['n_targets']}")
        )
    return rows


def summary_tables(metrics: dict[str, Any]) -> list[Table]:
    """The run table, the by-group table (when the metrics have groups) and the per-object
    table of a `metrics.json` dict."""
    instance("metrics", metrics, dict)
    th = metrics.get("thesis", {})
    run = Table(title="Tracking metrics (thesis §4.3, matching §7.3.1)", show_lines=False)
    run.add_column("metric")
    run.add_column("value", justify="right")
    rows = [
        ("targets (visible ≥ 5 s)", str(th.get("n_targets", "–"))),
        ("targets tracked", str(th.get("targets_tracked", "–"))),
        *_detectable_rows(metrics.get("detectable")),
        ("TPD (tracked / targets)", _f(th.get("tpd"))),
        ("mean time fraction tracked", _f(th.get("mean_tpd"))),
        (
            "TRF (mean / max tracks per target)",
            f"{_f(th.get('mean_trf'), '{:.2f}')} / {th.get('max_trf', '–')}",
        ),
        ("position RMSE (m)", _f(th.get("rmse"))),
        *(
            (
                f"  {kind}: tracked / targets, RMSE",
                f"{k['targets_tracked']} / {k['n_targets']}, {_f(k['rmse'])} m",
            )
            for kind, k in (th.get("by_kind") or {}).items()
        ),
        ("ANEES (position, χ² band)", _band(th.get("anees"))),
        ("ANIS (χ² band)", _band(th.get("anis"))),
    ]
    for sensor, c in (th.get("anis_by_sensor") or {}).items():
        rows.append((f"  ANIS {sensor}", _band(c)))
    rows.append(
        ("tracks / false tracks", f"{th.get('n_tracks', '–')} / {len(th.get('false_tracks', []))}")
    )
    for kind, ids in (th.get("excluded_tracks") or {}).items():
        rows.append((f"tracks on {kind}", f"[red]{len(ids)}[/red] {ids}"))
    walls = metrics.get("walls")
    if walls is not None:
        for key, name in (("tracks_on_walls", "walls"), ("tracks_on_moored_boats", "boat hulls")):
            ids = walls.get(key, [])
            rows.append(
                (f"tracks on {name} (scene)", f"[red]{len(ids)}[/red] {ids}" if ids else "0")
            )
        for key, name in (
            ("object_tracks_near_walls", "walls"),
            ("object_tracks_near_moored_boats", "boat hulls"),
        ):
            if ids := walls.get(key):
                rows.append((f"  objects' tracks near {name}", f"{len(ids)} {ids}"))
    mot = metrics.get("clear_mot")
    if mot:
        rows += [
            ("MOTA / MOTP (m)", f"{_f(mot['mota'])} / {_f(mot['motp'])}"),
            ("IDF1 / ID switches", f"{_f(mot['idf1'])} / {mot['switches']}"),
            ("precision / recall", f"{_f(mot['precision'])} / {_f(mot['recall'])}"),
        ]
    if metrics.get("hota"):
        h = metrics["hota"]
        rows.append(("HOTA (DetA, AssA)", f"{_f(h['hota'])} ({_f(h['deta'])}, {_f(h['assa'])})"))
    if metrics.get("gospa"):
        g = metrics["gospa"]
        rows.append(("mean GOSPA / OSPA (m)", f"{_f(g['gospa'])} / {_f(g['ospa'])}"))
    for sensor, d in (metrics.get("detectors") or {}).items():
        rows.append(
            (
                f"{sensor} detector TP / FN / CN max",
                f"{d['tp']} / {d['fn']} / {d['cn_max']} (TP rate {_f(d['tp_rate'])})",
            )
        )
    for name, value in rows:
        run.add_row(name, value)
    per = Table(title="Per object")
    det = {o["object_id"]: o for o in (metrics.get("detectable") or {}).get("objects", [])}
    cols = ["id", "kind", "target", "seen s", "TPD", "TT s", "TRF", "RMSE m", "ANEES"]
    if det:  # seconds some sensor physically saw it (visibility.csv; "(no)": not detectable)
        cols[4:4] = ["sensed s"]
    for col in cols:
        per.add_column(col, justify="right" if col not in ("kind",) else "left")
    for o in th.get("objects", []):
        a = o.get("anees")
        extra = []
        if det:
            d = det.get(o["object_id"])
            # the range rule's targets that are not detectable ones are marked
            short = d is not None and o["target"] and not d["target"]
            extra = ["–" if d is None else _f(d["seen_seconds"], "{:.1f}") + (" (no)" * short)]
        per.add_row(
            str(o.get("name", o["object_id"])),
            o["kind"].replace("moored_boat", "moored"),
            "yes" if o["target"] else "no",
            _f(o["visible_time"], "{:.1f}"),
            *extra,
            _f(o["tpd"], "{:.2f}"),
            _f(o["tt"], "{:.1f}"),
            str(o["trf"]),
            _f(o["rmse"]),
            _f(a["mean"] if a else None, "{:.2f}"),
        )
    groups = group_table(metrics)
    return [run, per] if groups is None else [run, groups, per]


def print_summary(metrics: dict[str, Any], console: Console | None = None) -> None:
    """Print the summary tables of a `metrics.json` dict."""
    console = console or Console()
    for t in summary_tables(metrics):
        console.print(t)
