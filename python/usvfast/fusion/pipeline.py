"""The radar + AIS situational picture: radar plots tracked by the usvfast tracker, radar
track identities kept across track breaks (paper §1.2), AIS targets interpolated at the scan
times (§1.1), radar ↔ AIS association (§1.3, J or χ²) and fused states by covariance
intersection. Every output is in the NED plane at `origin` and in WGS84.

Example::

    res = run_vts(plots, ais_targets, own, origin=(63.43, 10.39))
    res.rows          # list of FusedRow: time, track_id, mmsi, north, east, lat, lon, source
    res.associations  # (time, track_id, mmsi) whenever a pair starts or ends
"""

from __future__ import annotations

import math
import time as _time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike

from usvfast import geodesy
from usvfast import tracking as tk
from usvfast._validate import instance
from usvfast.fusion.ais_feed import AisTargets
from usvfast.fusion.associate import (
    Chi2Test,
    JCost,
    WindowAssociator,
    covariance_intersection,
    same_object,
)
from usvfast.kalman import constant_velocity_2d
from usvfast.radar.readers import RadarPlots

__all__ = ["FusedRow", "OwnShip", "TrackerConfig", "VtsResult", "radar_tracker", "run_vts"]


@dataclass(frozen=True)
class OwnShip:
    """The own ship (radar platform) over time: time (n,) UNIX s, north, east (n,) m in the
    NED plane, heading_deg (n,) true (NaN unknown). Positions are interpolated linearly."""

    time: np.ndarray
    north: np.ndarray
    east: np.ndarray
    heading_deg: np.ndarray

    def __post_init__(self) -> None:
        if len(self.time) == 0:
            raise ValueError("own: no own-ship position")
        if np.any(np.diff(self.time) < 0):
            raise ValueError("own: times must be in order")

    def at(self, t: ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(north, east, heading_deg) at times `t` (UNIX s), held at the ends."""
        tq = np.asarray(t, dtype=float)
        n = np.interp(tq, self.time, self.north)
        e = np.interp(tq, self.time, self.east)
        h = np.radians(self.heading_deg)
        ok = np.isfinite(h)
        if ok.any():
            c = np.interp(tq, self.time[ok], np.cos(h[ok]))
            s = np.interp(tq, self.time[ok], np.sin(h[ok]))
            head = np.degrees(np.arctan2(s, c)) % 360.0
        else:
            head = np.full(np.shape(tq), np.nan)
        return n, e, head


@dataclass(frozen=True)
class TrackerConfig:
    """Radar tracker parameters (JPDA, constant velocity; the Joyride choice of the tracker
    tests): q (m²/s³), sigma (m, noise per axis of plots given in NED), prob_detect,
    clutter_density (1/m²), prob_gate, delete_steps, init_steps, min_points,
    missed_distance, prior_velocity_var; range_std (m) and bearing_std_deg (deg) of plots
    given as (range, bearing), whose NED covariance is J diag(σ_r², σ_b²) Jᵀ with J the
    Jacobian of (r, b) -> (r cos b, r sin b) (converted measurements), floored at 1 m²;
    polar: how (range, bearing) plots update the tracks — "ekf" or "ukf" (the tracker's
    range–bearing sensor with the own ship as origin, Stone Soup's CartesianToBearingRange
    with the extended / unscented Kalman updater) or "converted" (the converted NED plot and
    covariance through the linear sensor)."""

    def __post_init__(self) -> None:
        if self.polar not in ("ekf", "ukf", "converted"):
            raise ValueError(f"polar: expected 'ekf', 'ukf' or 'converted', got {self.polar!r}")

    q: float = 5.0
    sigma: float = 25.0
    prob_detect: float = 0.8
    clutter_density: float = 5e-7
    prob_gate: float = 0.999
    delete_steps: int = 50
    init_steps: int = 3
    min_points: int = 2
    missed_distance: float = 5.0
    prior_velocity_var: float = 100.0
    range_std: float = 10.0
    bearing_std_deg: float = 1.0
    polar: Literal["ekf", "ukf", "converted"] = "ekf"


def radar_tracker(cfg: TrackerConfig, polar: bool = False) -> tk.Tracker:
    """The usvfast JPDA tracker for radar plots: sensor 0 linear in NED (R = sigma² I), and
    with `polar` sensor 1 range–bearing (z = (bearing rad, range m), `cfg.polar` update).
    The polar sensor needs the tracker's default `initiate_in_gates=True`; NED-only
    trackers withhold detections inside confirmed gates from the initiator (no duplicate
    tracks on one target)."""
    instance("cfg", cfg, TrackerConfig)
    sensors = [tk.Sensor.position(noise_std=cfg.sigma)]
    if polar:
        sensors.append(
            tk.Sensor.bearing_range(
                noise_std=(np.radians(cfg.bearing_std_deg), cfg.range_std),
                update="ukf" if cfg.polar == "ukf" else "ekf",
            )
        )
    return tk.Tracker(
        motion_model=constant_velocity_2d(cfg.q),
        sensors=sensors,
        association=tk.JPDA(
            prob_detect=cfg.prob_detect,
            prob_gate=cfg.prob_gate,
            clutter_density=cfg.clutter_density,
        ),
        deleter=tk.StepsSinceUpdate(cfg.delete_steps),
        initiator=tk.MultiMeasurementInitiator(
            prior_state=np.zeros(4),
            prior_covariance=np.diag([0.0, cfg.prior_velocity_var, 0.0, cfg.prior_velocity_var]),
            min_points=cfg.min_points,
            deleter=tk.StepsSinceUpdate(cfg.init_steps),
            missed_distance=cfg.missed_distance,
        ),
        initiate_in_gates=polar,
    )


@dataclass(frozen=True)
class FusedRow:
    """One target at one scan: time (UNIX s), track_id (radar identity, -1 for AIS-only),
    mmsi (-1 none), north, east (m), v_north, v_east (m/s), lat, lon (deg), source
    ("radar", "ais", "radar+ais"; "+camera" appended when matched), pos_std (m, sqrt of
    the mean position variance)."""

    time: float
    track_id: int
    mmsi: int
    north: float
    east: float
    v_north: float
    v_east: float
    lat: float
    lon: float
    source: str
    pos_std: float


@dataclass
class VtsResult:
    """What `run_vts` produced: rows (FusedRow per target per scan), radar_rows (the radar
    track alone, same layout, source "radar"), ais_rows (every AIS target at every scan,
    source "ais"), associations [(time, track_id, mmsi, "start" | "end")], plots (n, 3)
    (time, north, east) of every radar plot, own (s, 3) (time, north, east) at the scans,
    names {mmsi: name}, timings {stage: seconds}, scan_times (s,)."""

    rows: list[FusedRow]
    radar_rows: list[FusedRow]
    ais_rows: list[FusedRow]
    associations: list[tuple[float, int, int, str]]
    plots: np.ndarray
    own: np.ndarray
    names: dict[int, str]
    timings: dict[str, float] = field(default_factory=dict)
    scan_times: np.ndarray = field(default_factory=lambda: np.zeros(0))


def _plot_covariances(
    plots: RadarPlots, true_bearing: np.ndarray, cfg: TrackerConfig
) -> np.ndarray:
    """(n, 2, 2) NED covariance of each plot (m²): converted polar noise (at the plot's true
    bearing, degrees; NaN for plots not given polar), else sigma² I."""
    cov = np.tile(np.eye(2) * cfg.sigma**2, (len(plots), 1, 1))
    polar = np.isfinite(true_bearing)
    if polar.any():
        r = plots.range_m[polar]
        b = np.radians(true_bearing[polar])
        sb2 = np.radians(cfg.bearing_std_deg) ** 2
        c, s = np.cos(b), np.sin(b)
        rr, tt = cfg.range_std**2, (r * r) * sb2
        cov[polar, 0, 0] = c * c * rr + s * s * tt
        cov[polar, 1, 1] = s * s * rr + c * c * tt
        cov[polar, 0, 1] = cov[polar, 1, 0] = c * s * (rr - tt)
        cov[polar] += np.eye(2)  # floor: keeps plots at zero range positive definite
    return cov


def _plots_ned(
    plots: RadarPlots, own: OwnShip | None, origin: tuple[float, float]
) -> tuple[np.ndarray, np.ndarray]:
    """(n, 2) north, east of every plot in the plane: NED as given, TLL through geodesy,
    polar from the own ship (relative bearings turned by its heading); and (n,) the true
    bearing (deg) of polar plots, NaN for the others."""
    n, e = plots.north.copy(), plots.east.copy()
    true_bearing = np.full(len(n), np.nan)
    geo = np.isnan(n) & np.isfinite(plots.lat_deg)
    if geo.any():
        gn, ge, _ = geodesy.geodetic2ned(
            plots.lat_deg[geo], plots.lon_deg[geo], 0.0, origin[0], origin[1], 0.0
        )
        n[geo], e[geo] = gn, ge
    polar = np.isnan(n) & np.isfinite(plots.range_m)
    if polar.any():
        if own is None:
            raise ValueError("own: polar radar plots (range, bearing) need the own-ship track")
        on, oe, head = own.at(plots.time[polar])
        brg = plots.bearing_deg[polar].copy()
        rel = ~plots.bearing_true[polar]
        if np.any(rel & np.isnan(head)):
            raise ValueError("own: relative radar bearings need the own-ship heading")
        brg[rel] = brg[rel] + head[rel]
        true_bearing[polar] = brg
        b = np.radians(brg)
        n[polar] = on + plots.range_m[polar] * np.cos(b)
        e[polar] = oe + plots.range_m[polar] * np.sin(b)
    return np.stack([n, e], axis=1), true_bearing


def _row(t, tid, mmsi, x, p, source) -> FusedRow:
    """A row without its WGS84 position (filled in bulk by `_with_geodetic`)."""
    lat = lon = math.nan
    return FusedRow(
        float(t),
        int(tid),
        int(mmsi),
        float(x[0]),
        float(x[2]),
        float(x[1]),
        float(x[3]),
        float(lat),
        float(lon),
        source,
        float(math.sqrt(max((p[0, 0] + p[2, 2]) / 2.0, 0.0))),
    )


def _with_geodetic(rows: list[FusedRow], origin: tuple[float, float]) -> list[FusedRow]:
    if not rows:
        return rows
    n = np.array([r.north for r in rows])
    e = np.array([r.east for r in rows])
    lat, lon, _ = geodesy.ned2geodetic(n, e, 0.0, origin[0], origin[1], 0.0)
    return [replace(r, lat=float(a), lon=float(b)) for r, a, b in zip(rows, lat, lon, strict=True)]


def run_vts(
    plots: RadarPlots,
    ais: AisTargets | None,
    own: OwnShip | None,
    *,
    origin: tuple[float, float],
    tracker: TrackerConfig | None = None,
    method: JCost | Chi2Test | None = None,
    window: int = 8,
    t_d: float = 30.0,
    radius: float = 60.0,
    fresh: float = 15.0,
    progress: Callable[[int, int], None] | None = None,
) -> VtsResult:
    """Track the radar plots, give the tracks AIS identities and fuse them (module docstring).

    t_d (s), radius (m): §1.2 identity — a new radar track starting within `radius` of where a
    track lost at most `t_d` seconds before would be is the same object and keeps its id (and
    its AIS identity). fresh (s): AIS targets whose report is older are not compared (their
    pairs are kept, see `WindowAssociator.update`). tracker: default `TrackerConfig()`;
    method: default `JCost()`. progress(done, total) is called after each scan. Raises
    ValueError when plots are polar without an own ship."""
    instance("plots", plots, RadarPlots)
    if ais is not None:
        instance("ais", ais, AisTargets)
    if own is not None:
        instance("own", own, OwnShip)
    if tracker is not None:
        instance("tracker", tracker, TrackerConfig)
    if method is not None:
        instance("method", method, JCost, Chi2Test)
    t_start = _time.perf_counter()
    timings: dict[str, float] = {}
    cfg = tracker or TrackerConfig()
    xy, true_bearing = _plots_ned(plots, own, origin)
    plot_cov = _plot_covariances(plots, true_bearing, cfg)
    polar = np.isfinite(true_bearing) if cfg.polar != "converted" else np.zeros(len(xy), bool)
    meas, sensor, origins = xy.copy(), polar.astype(np.int64), np.zeros((len(xy), 2))
    if polar.any():
        # Range–bearing rows: z = (true bearing rad, range m) from the own ship.
        meas[polar] = np.column_stack([np.radians(true_bearing[polar]), plots.range_m[polar]])
        plot_cov[polar] = np.diag([np.radians(cfg.bearing_std_deg) ** 2, cfg.range_std**2])
        assert own is not None  # _plots_ned refuses polar plots without an own ship
        on, oe, _ = own.at(plots.time[polar])
        origins[polar] = np.column_stack([on, oe])
    scan_times, scan_index = plots.scans()
    trk = radar_tracker(cfg, polar=bool(polar.any()))
    assoc = WindowAssociator(method or JCost(), window=window)
    t0 = float(scan_times[0]) if len(scan_times) else 0.0
    names = dict(ais.names) if ais is not None else {}
    rows: list[FusedRow] = []
    radar_rows: list[FusedRow] = []
    ais_rows: list[FusedRow] = []
    events: list[tuple[float, int, int, str]] = []
    alias: dict[int, int] = {}  # tracker id -> radar identity
    last_seen: dict[int, tuple[float, np.ndarray]] = {}  # identity -> (time, state)
    order = np.argsort(scan_index, kind="stable")
    bounds = np.searchsorted(scan_index[order], np.arange(len(scan_times) + 1))
    timings["read"] = _time.perf_counter() - t_start
    t_track = t_ais = t_assoc = 0.0
    prev_pairs: dict[int, int] = {}
    for s, t in enumerate(scan_times.tolist()):
        a = _time.perf_counter()
        rows_s = order[bounds[s] : bounds[s + 1]]
        rows_s = rows_s[np.all(np.isfinite(xy[rows_s]), axis=1)]  # empty (AIS-only) scans
        tracks = trk.step(
            t - t0,
            meas[rows_s],
            sensor[rows_s],
            covariances=plot_cov[rows_s],
            origins=origins[rows_s],
        )
        b = _time.perf_counter()
        t_track += b - a
        ids = []
        live = {alias[i] for i in tracks.ids.tolist() if i in alias}
        for k, tid in enumerate(tracks.ids.tolist()):
            if tid not in alias:
                alias[tid] = _inherit(tid, tracks.states[k], t, last_seen, live, t_d, radius)
                live.add(alias[tid])
            ids.append(alias[tid])
        for k, ident in enumerate(ids):
            last_seen[ident] = (t, tracks.states[k])
        st = ais.states_at(t) if ais is not None else None
        c = _time.perf_counter()
        t_ais += c - b
        if st is not None:
            pairs = assoc.update(
                ids, tracks.states, tracks.covariances, st.mmsi, st.state, st.cov, st.age <= fresh
            )
        else:
            pairs = {}
        for ident, m in pairs.items():
            if prev_pairs.get(ident) != m:
                events.append((t, ident, m, "start"))
        for ident, m in prev_pairs.items():
            if pairs.get(ident) != m:
                events.append((t, ident, m, "end"))
        prev_pairs = pairs
        paired_mmsi = set(pairs.values())
        ais_index = {int(m): j for j, m in enumerate(st.mmsi)} if st is not None else {}
        for k, ident in enumerate(ids):
            x, p = tracks.states[k], tracks.covariances[k]
            radar_rows.append(_row(t, ident, -1, x, p, "radar"))
            m = pairs.get(ident, -1)
            if st is not None and m >= 0 and m in ais_index:
                j = ais_index[m]
                xf, pf, _ = covariance_intersection(x, p, st.state[j], st.cov[j])
                rows.append(_row(t, ident, m, xf, pf, "radar+ais"))
            else:
                rows.append(_row(t, ident, -1, x, p, "radar"))
        if st is not None:
            for j, m in enumerate(st.mmsi.tolist()):
                r = _row(t, -1, m, st.state[j], st.cov[j], "ais")
                ais_rows.append(r)
                if m not in paired_mmsi:
                    rows.append(r)
        t_assoc += _time.perf_counter() - c
        if progress is not None:
            progress(s + 1, len(scan_times))
    a = _time.perf_counter()
    rows, radar_rows, ais_rows = (_with_geodetic(x, origin) for x in (rows, radar_rows, ais_rows))
    t_assoc += _time.perf_counter() - a
    timings |= {"track": t_track, "ais": t_ais, "associate+fuse": t_assoc}
    own_arr = np.zeros((0, 3))
    if own is not None and len(scan_times):
        on, oe, _ = own.at(scan_times)
        own_arr = np.stack([scan_times, on, oe], axis=1)
    return VtsResult(
        rows,
        radar_rows,
        ais_rows,
        events,
        np.column_stack([plots.time, xy])[np.all(np.isfinite(xy), axis=1)],
        own_arr,
        names,
        timings,
        scan_times,
    )


def _inherit(tid, state, t, last_seen, live, t_d, radius) -> int:
    """The identity of a newly confirmed tracker track: that of a track (not `live`) lost
    within t_d s whose predicted position lies within `radius` m (§1.2), else the tracker's
    own id (never used as an identity before)."""
    best, best_d = None, math.inf
    for ident, (t_old, x_old) in last_seen.items():
        if ident in live or t_old >= t:
            continue
        if same_object(x_old[[0, 2]], x_old[[1, 3]], t_old, state[[0, 2]], t, t_d, radius):
            d = math.hypot(*(state[[0, 2]] - (x_old[[0, 2]] + x_old[[1, 3]] * (t - t_old))))
            if d < best_d:
                best, best_d = ident, d
    return best if best is not None else int(tid)
