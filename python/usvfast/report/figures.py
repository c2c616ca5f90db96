"""The pictures of a run: the map (`map.png`), the NIS plot (`nis.png`, the thesis's Fig.
6.5) and the per-object position errors (`errors.png`).

Maps are drawn north up: east (m) on x, north (m) on y, equal aspect, in the run's local NED
frame. Figures are built on `matplotlib.figure.Figure` (no pyplot state), so they are safe to
draw from any thread and need no display.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Ellipse, Polygon
from scipy.stats import chi2

from usvfast._validate import as_float_array, instance
from usvfast.metrics.consistency import average_consistency, chi2_band
from usvfast.metrics.protocol import Matches
from usvfast.metrics.tables import Detections, Innovations, Nav, Tracks, Truth
from usvfast.report.evaluate import is_closed, moored_outline

SENSOR_STYLE = {
    "lidar": {"color": "#1f77b4", "marker": "."},
    "camera": {"color": "#ff7f0e", "marker": "x"},
}
TRUTH_COLOR = "#2ca02c"
USV_COLOR = "black"
WALL_COLOR = "#8c8c8c"


def track_colors(ids: np.ndarray) -> dict[int, Any]:
    """A distinct colour per track id (tab20 cycled, in id order)."""
    ids = as_float_array("ids", ids).ravel()
    from matplotlib import colormaps

    cmap = colormaps["tab20"]
    return {int(i): cmap((k * 2 % 20 + k // 10 % 2) / 20) for k, i in enumerate(np.unique(ids))}


def ellipse(mean_ne: np.ndarray, cov_ne: np.ndarray, n_sigma: float = 2.0, **kw: Any) -> Ellipse:
    """The `n_sigma` ellipse of a NED position covariance (2, 2) m², in map axes (x = east,
    y = north)."""
    mean_ne = as_float_array("mean_ne", mean_ne, ndim=1)
    cov_ne = as_float_array("cov_ne", cov_ne, ndim=2)
    if mean_ne.shape != (2,) or cov_ne.shape != (2, 2):
        raise ValueError(
            f"mean_ne, cov_ne: expected (2,) and (2, 2), got {mean_ne.shape}, {cov_ne.shape}"
        )
    # covariance in plot axes (east, north)
    c = np.array([[cov_ne[1, 1], cov_ne[0, 1]], [cov_ne[0, 1], cov_ne[0, 0]]])
    vals, vecs = np.linalg.eigh(c)
    vals = np.clip(vals, 0.0, None)
    angle = np.degrees(np.arctan2(vecs[1, 1], vecs[0, 1]))
    w, h = 2 * n_sigma * np.sqrt(vals[1]), 2 * n_sigma * np.sqrt(vals[0])
    return Ellipse((mean_ne[1], mean_ne[0]), w, h, angle=angle, **kw)


def draw_scene(ax: Axes, scene: dict[str, Any] | None) -> list[Any]:
    """Harbour walls (grey, polygons filled) and moored boats (brown outlines); legend handles."""
    instance("ax", ax, Axes)
    if scene is not None:
        instance("scene", scene, dict)
    handles: list[Any] = []
    if not scene:
        return handles
    for w in scene.get("walls", []):
        p = np.asarray(w, float).reshape(-1, 2)
        if is_closed(p):
            ax.add_patch(Polygon(p[:, ::-1], closed=True, fc=WALL_COLOR, ec="#555555", alpha=0.6))
        elif len(p) >= 2:
            ax.plot(p[:, 1], p[:, 0], color="#555555", lw=3, solid_capstyle="butt")
    if scene.get("walls"):
        handles.append(Line2D([], [], color="#555555", lw=3, label="harbour walls"))
    for b in scene.get("moored", []):
        ax.add_patch(
            Polygon(moored_outline(b)[:, ::-1], closed=True, fc="#d9b38c", ec="#8b5a2b", lw=1.2)
        )
    if scene.get("moored"):
        handles.append(
            Line2D([], [], color="#8b5a2b", marker="s", ls="", mfc="#d9b38c", label="moored boats")
        )
    return handles


def map_extent(
    tracks: Tracks,
    detections: Detections | None,
    nav: Nav | None,
    truth: Truth | None,
    near: float = 30.0,
) -> list[np.ndarray]:
    """The points a map frames: tracks, detections, the USV path, and the truth within `near`
    m of the USV path (all of it without a path), so that far-away objects that were never
    in view do not shrink the action to a corner."""
    instance("tracks", tracks, Tracks)
    for name, v, kind in (
        ("detections", detections, Detections),
        ("nav", nav, Nav),
        ("truth", truth, Truth),
    ):
        if v is not None:
            instance(name, v, kind)
    parts = [tracks.positions]
    if detections is not None and len(detections.time):
        parts.append(detections.positions)
    if nav is not None and len(nav.time):
        parts.append(nav.positions)
        if truth is not None and len(truth.time):
            from scipy.spatial import cKDTree  # pyright: ignore[reportAttributeAccessIssue]

            d, _ = cKDTree(nav.positions).query(truth.positions)
            parts.append(truth.positions[d <= near])
    elif truth is not None:
        parts.append(truth.positions)
    return parts


def fit_limits(ax: Axes, parts: list[np.ndarray], margin: float = 5.0) -> None:
    """Map axes limits around `parts` (arrays of (n, 2) NED points; 0.5–99.5 percentiles plus
    `margin` m), widened so that equal metres fill the axes box."""
    instance("ax", ax, Axes)
    pts = np.concatenate([p.reshape(-1, 2) for p in parts if len(p)] or [np.zeros((1, 2))])
    pts = pts[np.all(np.isfinite(pts), axis=1)]
    lo, hi = np.percentile(pts, 0.5, axis=0) - margin, np.percentile(pts, 99.5, axis=0) + margin
    # widen the shorter side so that equal metres fill the axes box
    pos = ax.get_position()
    fw, fh = ax.figure.get_size_inches()  # pyright: ignore[reportAttributeAccessIssue]
    ratio = (pos.width * fw) / max(pos.height * fh, 1e-9)  # box width / height
    mid, half = (lo + hi) / 2, (hi - lo) / 2  # (north, east)
    if half[1] < half[0] * ratio:
        half[1] = half[0] * ratio
    else:
        half[0] = half[1] / ratio
    ax.set_xlim(mid[1] - half[1], mid[1] + half[1])
    ax.set_ylim(mid[0] - half[0], mid[0] + half[0])
    ax.set_aspect("equal", adjustable="box")


def draw_usv(ax: Axes, nav: Nav | None, upto: float | None = None) -> list[Any]:
    """USV path (black) and a heading arrow at its last pose; legend handles."""
    instance("ax", ax, Axes)
    if nav is not None:
        instance("nav", nav, Nav)
    if nav is None or len(nav.time) == 0:
        return []
    sel = np.ones(len(nav.time), bool) if upto is None else nav.time <= upto
    if not sel.any():
        return []
    p = nav.positions[sel]
    ax.plot(p[:, 1], p[:, 0], color=USV_COLOR, lw=1.5, zorder=4)
    h = np.radians(nav.heading_deg[sel][-1])
    ax.annotate(
        "",
        xy=(p[-1, 1] + 4 * np.sin(h), p[-1, 0] + 4 * np.cos(h)),
        xytext=(p[-1, 1], p[-1, 0]),
        arrowprops={"arrowstyle": "-|>", "color": USV_COLOR, "lw": 2},
        zorder=6,
    )
    ax.plot(p[-1, 1], p[-1, 0], "o", color=USV_COLOR, ms=6, zorder=6)
    return [Line2D([], [], color=USV_COLOR, lw=1.5, marker="o", ms=4, label="USV path (heading)")]


def draw_truth(ax: Axes, truth: Truth | None, upto: float | None = None, label: bool = True):
    """Truth paths (green dashed) with object labels; legend handles."""
    instance("ax", ax, Axes)
    if truth is not None:
        instance("truth", truth, Truth)
    if truth is None or len(truth.time) == 0:
        return []
    kinds = truth.kinds()
    for oid, kind in kinds.items():
        sel = truth.object_id == oid
        if upto is not None:
            sel &= truth.time <= upto
        if not sel.any():
            continue
        p = truth.positions[sel][np.argsort(truth.time[sel])]
        style = ":" if kind == "moored_boat" else "--"
        ax.plot(p[:, 1], p[:, 0], style, color=TRUTH_COLOR, lw=1.2, zorder=3)
        ax.plot(p[-1, 1], p[-1, 0], "o", mfc="none", mec=TRUTH_COLOR, ms=7, zorder=3)
        if label:
            ax.annotate(
                truth.name(oid) if truth.names else f"{oid} {kind}",
                (p[-1, 1], p[-1, 0]),
                xytext=(4, -10),
                textcoords="offset points",
                fontsize=7,
                color="#1a661a",
            )
    return [
        Line2D([], [], color=TRUTH_COLOR, ls="--", marker="o", mfc="none", label="ground truth")
    ]


def draw_detections(
    ax: Axes,
    det: Detections | None,
    since: float | None = None,
    upto: float | None = None,
    size: float = 9.0,
) -> list[Any]:
    """Detections by sensor (LiDAR blue dots, camera orange crosses); legend handles."""
    instance("ax", ax, Axes)
    if det is not None:
        instance("det", det, Detections)
    if det is None or len(det.time) == 0:
        return []
    handles = []
    for sensor in sorted(set(det.sensor.tolist())):
        sel = det.sensor == sensor
        if since is not None:
            sel &= det.time >= since
        if upto is not None:
            sel &= det.time <= upto
        st = SENSOR_STYLE.get(sensor, {"color": "#9467bd", "marker": "+"})
        p = det.positions[sel]
        ax.scatter(p[:, 1], p[:, 0], s=size, c=st["color"], marker=st["marker"], alpha=0.5, lw=0.6)
        handles.append(
            Line2D(
                [], [], color=st["color"], marker=st["marker"], ls="", label=f"{sensor} detections"
            )
        )
    return handles


def draw_tracks(
    ax: Axes,
    tracks: Tracks,
    colors: dict[int, Any],
    *,
    upto: float | None = None,
    ellipses_per_track: int = 12,
    label: bool = True,
) -> list[Any]:
    """Track lines coloured by id, 2σ covariance ellipses along them (semi-transparent, as
    the thesis's Fig. 6.1), the id at each track's last point; legend handles."""
    instance("ax", ax, Axes)
    instance("tracks", tracks, Tracks)
    has_cov = np.all(np.isfinite(tracks.covariances.reshape(len(tracks.time), 4)), axis=1)
    placed: list[np.ndarray] = []
    for tid in np.unique(tracks.track_id):
        sel = tracks.track_id == tid
        if upto is not None:
            sel &= tracks.time <= upto
        if not sel.any():
            continue
        idx = np.flatnonzero(sel)[np.argsort(tracks.time[sel], kind="stable")]
        p = tracks.positions[idx]
        col = colors[int(tid)]
        # in an animation frame, a track without an update in the last second has ended
        alive = upto is None or upto - tracks.time[idx[-1]] <= 1.0
        ax.plot(
            p[:, 1],
            p[:, 0],
            "-",
            color=col,
            lw=2.0 if alive else 1.0,
            alpha=1 if alive else 0.4,
            zorder=5,
        )
        step = max(1, len(idx) // ellipses_per_track)
        pick = list(idx[::step])
        if upto is not None:
            pick = [idx[-1]] if alive else []
        for i in pick:
            if has_cov[i]:
                ax.add_patch(
                    ellipse(tracks.positions[i], tracks.covariances[i], fc=col, ec=col, alpha=0.25)
                )
        if label and alive:
            # labels of tracks ending close together are stacked so each stays readable
            crowd = sum(np.linalg.norm(q - p[-1]) < 4.0 for q in placed)
            placed.append(p[-1])
            ax.annotate(
                f"T{tid}",
                (p[-1, 1], p[-1, 0]),
                xytext=(4, 4 + 9 * crowd),
                textcoords="offset points",
                fontsize=8,
                color=col,
                weight="bold",
            )
    if len(tracks.time) == 0:
        return []
    first = colors[int(tracks.track_id[0])]
    return [
        Line2D([], [], color=first, lw=2, label="tracks (colour per id, 2σ ellipses)"),
    ]


def map_figure(
    tracks: Tracks,
    *,
    detections: Detections | None = None,
    nav: Nav | None = None,
    truth: Truth | None = None,
    scene: dict[str, Any] | None = None,
    title: str = "usvfast run",
    origin: tuple[float, float, float] | None = None,
) -> Figure:
    """The run's map (module doc): harbour, USV path, detections, truth, tracks."""
    instance("tracks", tracks, Tracks)
    fig = Figure(figsize=(9, 8), dpi=110)
    ax = fig.add_subplot(1, 1, 1)
    handles = draw_scene(ax, scene)
    handles += draw_detections(ax, detections)
    handles += draw_truth(ax, truth)
    handles += draw_usv(ax, nav)
    handles += draw_tracks(ax, tracks, track_colors(tracks.track_id))
    parts = map_extent(tracks, detections, nav, truth)
    fit_limits(ax, parts)
    ax.set_xlabel("east (m)")
    ax.set_ylabel("north (m)")
    sub = ""
    if origin is not None:
        sub = f"\nNED origin {origin[0]:.6f}°, {origin[1]:.6f}° — north up"
    ax.set_title(title + sub, fontsize=11)
    ax.grid(True, alpha=0.3)
    ax.legend(handles=handles, loc="best", fontsize=8, framealpha=0.85)
    fig.tight_layout()
    fit_limits(ax, parts)  # again, for the box tight_layout settled on
    return fig


def nis_figure(innovations: Innovations, confidence: float = 0.95, title: str = "") -> Figure:
    """NIS of every track update over time, by sensor, with the per-update χ² band, a moving
    ANIS and the ANIS band of the whole run (the thesis's Fig. 6.5); right: the NIS histogram
    against the χ² density."""
    instance("innovations", innovations, Innovations)
    fig = Figure(figsize=(11, 4.8), dpi=110)
    ax, hx = fig.subplots(1, 2, gridspec_kw={"width_ratios": [2.6, 1]})
    t0 = float(innovations.time.min()) if len(innovations.time) else 0.0
    dof = int(np.bincount(innovations.dof).argmax()) if len(innovations.dof) else 2
    for sensor in sorted(set(innovations.sensor.tolist())):
        sel = innovations.sensor == sensor
        st = SENSOR_STYLE.get(sensor, {"color": "#9467bd", "marker": "+"})
        ax.scatter(
            innovations.time[sel] - t0,
            innovations.nis[sel],
            s=8,
            c=st["color"],
            marker=st["marker"],
            alpha=0.5,
            lw=0.7,
            label=f"NIS {sensor} ({sel.sum()} updates)",
        )
    lo1, hi1 = chi2_band(dof, 1, confidence)
    ax.axhline(lo1, color="grey", ls="--", lw=1)
    ax.axhline(hi1, color="grey", ls="--", lw=1, label=f"{confidence:.0%} band, one update")
    n = len(innovations.nis)
    c = average_consistency(innovations.nis, innovations.dof, confidence, innovations.gate)
    if c is not None:
        order = np.argsort(innovations.time, kind="stable")
        t, v = innovations.time[order] - t0, innovations.nis[order]
        w = max(1, min(50, n // 10))
        mov = np.convolve(v, np.ones(w) / w, mode="valid")
        ax.plot(t[w - 1 :], mov, color="black", lw=1.5, label=f"moving ANIS ({w} updates)")
        lo, hi, anis = c.lower, c.upper, c.mean
        inside = "inside" if c.inside else "OUTSIDE"
        gated = f", gated P_G {c.gate:g}" if c.gate is not None else ""
        ax.axhspan(lo, hi, color="#2ca02c", alpha=0.2, label=f"ANIS band ({n} updates{gated})")
        ax.axhline(anis, color="#2ca02c", lw=2, label=f"ANIS = {anis:.2f} ({inside})")
    top = 1.2 * max(hi1, float(np.percentile(innovations.nis, 99)) if n else 0.0)
    if n:
        hx.hist(
            np.clip(v, 0, top), bins=40, range=(0, top), density=True, color="#bbbbbb", label="NIS"
        )
    x = np.linspace(1e-3, top, 200)
    hx.plot(x, chi2.pdf(x, dof), color="black", label=f"χ²({dof}) density")
    hx.set_xlabel("NIS")
    hx.set_ylabel("density")
    hx.legend(fontsize=8)
    hx.set_title("distribution", fontsize=10)
    ax.set_yscale("log")
    ax.set_xlabel("time since start (s)")
    ax.set_ylabel(f"NIS (dof {dof}, log scale)")
    ax.set_title(title or "Normalised innovation squared per track update", fontsize=11)
    ax.grid(True, which="both", alpha=0.25)
    ax.legend(fontsize=7.5, loc="lower left", ncol=2, framealpha=0.85)
    fig.tight_layout()
    return fig


def errors_figure(
    matches: Matches,
    kinds: dict[int, str],
    targets: list[int],
    *,
    confidence: float = 0.95,
    cap: float = 5.0,
    names: dict[int, str] | None = None,
) -> Figure:
    """Per-object position error |track − truth| (m) over time (top) and NEES (bottom, log,
    with the one-sample χ²(2) band); one colour per target object, labelled by `names` (the
    truth file's ids) when given."""
    instance("matches", matches, Matches)
    from matplotlib import colormaps

    def label(oid: int) -> str:
        return names[oid] if names and oid in names else f"{oid} {kinds.get(oid, '')}"

    fig = Figure(figsize=(11, 7), dpi=110)
    ax, nx = fig.subplots(2, 1, sharex=True)
    t0 = float(matches.time.min()) if len(matches.time) else 0.0
    cmap = colormaps["tab10" if len(targets) <= 10 else "tab20"]
    n_col = cmap.N
    for k, oid in enumerate(targets):
        sel = matches.object_id == oid
        if not sel.any():
            continue
        t = matches.time[sel] - t0
        e = np.linalg.norm(matches.error[sel], axis=1)
        rmse = float(np.sqrt(np.mean(e**2)))
        col = cmap(k % n_col)
        # break the line where the object was not matched for more than 1 s
        gaps = np.flatnonzero(np.diff(t) > 1.0) + 1
        for j, (ts, es) in enumerate(zip(np.split(t, gaps), np.split(e, gaps), strict=True)):
            ax.plot(
                ts,
                es,
                color=col,
                lw=1.3,
                label=f"{label(oid)} (RMSE {rmse:.2f} m)" if j == 0 else None,
            )
        nees = matches.nees[sel]
        ok = np.isfinite(nees)
        nx.plot(t[ok], nees[ok], ".", ms=3, color=col)
    lo, hi = chi2_band(2, 1, confidence)
    nx.axhline(lo, color="grey", ls="--", lw=1)
    nx.axhline(hi, color="grey", ls="--", lw=1, label=f"{confidence:.0%} band, one sample")
    nx.set_yscale("log")
    nx.set_ylabel("NEES (position, 2 dof)")
    nx.set_xlabel("time since first match (s)")
    nx.grid(True, which="both", alpha=0.25)
    nx.legend(fontsize=8, loc="upper right")
    ax.set_ylabel("position error (m)")
    ax.set_ylim(0, None)
    ax.set_title(
        f"Position error of the matched track per object (±1 s window, {cap:g} m cap)",
        fontsize=11,
    )
    ax.grid(True, alpha=0.3)
    if any(np.any(matches.object_id == o) for o in targets):
        if len(targets) > 6:  # many objects: the legend beside the plots, not over them
            ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0)
        else:
            ax.legend(fontsize=8, loc="upper right", ncol=2)
    else:
        ax.text(0.5, 0.5, "no track matched any object", transform=ax.transAxes, ha="center")
    fig.tight_layout()
    return fig


def save(fig: Figure, path: Path) -> Path:
    """Write a figure as PNG and return the path."""
    fig.savefig(path)
    return path
