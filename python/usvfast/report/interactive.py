"""An interactive map of a run (`map.html`, plotly): the same layers as `map.png` — harbour,
USV path, detections by sensor, truth, tracks — with the time and id of every point on hover,
zoom and layer toggles. East on x, north on y, equal metres. Needs plotly (the `report`
extra); `write_html_map` returns None without it.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from usvfast.metrics.tables import Detections, Nav, Tracks, Truth
from usvfast.report.evaluate import is_closed, moored_outline
from usvfast.report.figures import SENSOR_STYLE, map_extent


def _hex(rgba: tuple[float, ...]) -> str:
    return "#" + "".join(f"{round(255 * c):02x}" for c in rgba[:3])


def write_html_map(
    path: Path,
    tracks: Tracks,
    *,
    detections: Detections | None = None,
    nav: Nav | None = None,
    truth: Truth | None = None,
    scene: dict[str, Any] | None = None,
    title: str = "usvfast run",
) -> Path | None:
    """Write the interactive map to `path` (one self-contained HTML file, plotly.js inlined);
    None when plotly is not installed."""
    try:
        import plotly.graph_objects as go
    except ImportError:
        return None
    from usvfast.report.figures import track_colors

    fig = go.Figure()
    t0 = float(nav.time.min()) if nav is not None and len(nav.time) else 0.0
    for w in (scene or {}).get("walls", []):
        p = np.asarray(w, float).reshape(-1, 2)
        fill = "toself" if is_closed(p) else None
        fig.add_trace(
            go.Scatter(
                x=p[:, 1],
                y=p[:, 0],
                mode="lines",
                fill=fill,
                line={"color": "#555555", "width": 3},
                name="harbour walls",
                legendgroup="walls",
                showlegend=False,
                hoverinfo="skip",
            )
        )
    for b in (scene or {}).get("moored", []):
        p = moored_outline(b)
        p = np.vstack([p, p[:1]])
        fig.add_trace(
            go.Scatter(
                x=p[:, 1],
                y=p[:, 0],
                mode="lines",
                fill="toself",
                line={"color": "#8b5a2b"},
                fillcolor="#d9b38c",
                name=f"moored {b.get('id', '')}",
                legendgroup="moored",
                showlegend=False,
            )
        )
    if detections is not None:
        for sensor in sorted(set(detections.sensor.tolist())):
            k = detections.sensor == sensor
            st = SENSOR_STYLE.get(sensor, {"color": "#9467bd"})
            fig.add_trace(
                go.Scatter(
                    x=detections.positions[k, 1],
                    y=detections.positions[k, 0],
                    mode="markers",
                    marker={"size": 4, "color": st["color"], "opacity": 0.5},
                    name=f"{sensor} detections",
                    customdata=detections.time[k] - t0,
                    hovertemplate="t=%{customdata:.1f} s<br>e=%{x:.2f} n=%{y:.2f}",
                )
            )
    if truth is not None:
        for oid, kind in truth.kinds().items():
            k = truth.object_id == oid
            o = np.argsort(truth.time[k])
            p, tt = truth.positions[k][o], truth.time[k][o] - t0
            fig.add_trace(
                go.Scatter(
                    x=p[:, 1],
                    y=p[:, 0],
                    mode="lines",
                    line={"color": "#2ca02c", "dash": "dash"},
                    name=f"truth {truth.name(oid)} ({kind})",
                    legendgroup="truth",
                    customdata=tt,
                    hovertemplate="t=%{customdata:.1f} s<br>e=%{x:.2f} n=%{y:.2f}",
                )
            )
    if nav is not None and len(nav.time):
        fig.add_trace(
            go.Scatter(
                x=nav.positions[:, 1],
                y=nav.positions[:, 0],
                mode="lines",
                line={"color": "black", "width": 2},
                name="USV path",
                customdata=np.column_stack([nav.time - t0, nav.heading_deg]),
                hovertemplate="t=%{customdata[0]:.1f} s, heading %{customdata[1]:.0f}°",
            )
        )
    colors = track_colors(tracks.track_id)
    for tid in np.unique(tracks.track_id):
        k = tracks.track_id == tid
        o = np.argsort(tracks.time[k], kind="stable")
        p, tt = tracks.positions[k][o], tracks.time[k][o] - t0
        fig.add_trace(
            go.Scatter(
                x=p[:, 1],
                y=p[:, 0],
                mode="lines+markers",
                marker={"size": 3},
                line={"color": _hex(colors[int(tid)]), "width": 2},
                name=f"track {tid}",
                customdata=tt,
                hovertemplate=f"track {tid}<br>t=%{{customdata:.1f}} s"
                "<br>e=%{x:.2f} n=%{y:.2f}",
            )
        )
    pts = np.concatenate([q.reshape(-1, 2) for q in map_extent(tracks, detections, nav, truth)])
    if len(pts):
        lo, hi = pts.min(0) - 5, pts.max(0) + 5
        fig.update_xaxes(range=[lo[1], hi[1]])
        fig.update_yaxes(range=[lo[0], hi[0]])
    fig.update_layout(
        title=title,
        xaxis_title="east (m)",
        yaxis_title="north (m)",
        template="plotly_white",
        yaxis={"scaleanchor": "x", "scaleratio": 1},
        height=800,
    )
    fig.write_html(path, include_plotlyjs=True, full_html=True)
    return path
