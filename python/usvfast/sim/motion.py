"""Motion of everything in the simulated harbour: smoothed waypoint paths (the USV and the
moving vessels), drifting floating objects, and the wave-driven roll, pitch and heave of the
USV.

Times are seconds since the start of the recording (the writers add the UNIX epoch); the
world frame is local NED in metres (north, east), headings in radians clockwise from north.
Every function is vectorised over time and deterministic (random parts are drawn once, from
a numpy Generator, when the object is built).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from usvfast._validate import as_float_array


def chaikin(points: np.ndarray, iterations: int = 4, closed: bool = False) -> np.ndarray:
    """Corner-cutting smoothing of a polyline (k, 2) (Chaikin): each pass replaces every edge
    by its 1/4 and 3/4 points, so corners become arcs of a few metres. Open polylines keep
    their end points."""
    points = as_float_array("points", points, ndim=2)
    if points.shape[1] != 2 or len(points) < 2:
        raise ValueError(f"points: expected (k >= 2, 2), got shape {points.shape}")
    if not 0 <= iterations <= 10:
        raise ValueError(f"iterations: expected 0..10, got {iterations}")
    p = np.asarray(points, dtype=np.float64)
    for _ in range(iterations):
        a = p if closed else p[:-1]
        b = np.roll(p, -1, axis=0) if closed else p[1:]
        q = np.empty((2 * len(a), 2))
        q[0::2] = 0.75 * a + 0.25 * b
        q[1::2] = 0.25 * a + 0.75 * b
        p = q if closed else np.vstack([p[:1], q, p[-1:]])
    return p


@dataclass
class PathMotion:
    """Motion along a smoothed polyline at a speed profile, looping when `closed`.

    vertices : (k, 2) smoothed path (north, east) m. speed : m/s, constant, or modulated by
    `speed_wobble` (relative amplitude) at `wobble_period` s. start : arc length at t = 0, m.
    """

    vertices: np.ndarray
    speed: float
    closed: bool = True
    start: float = 0.0
    speed_wobble: float = 0.0
    wobble_period: float = 20.0

    def __post_init__(self) -> None:
        v = as_float_array("vertices", self.vertices, ndim=2)
        if v.shape[1] != 2 or len(v) < 2:
            raise ValueError(f"vertices: expected (k >= 2, 2) points, got shape {v.shape}")
        for name in ("speed", "start", "speed_wobble", "wobble_period"):
            if not math.isfinite(float(getattr(self, name))):
                raise ValueError(f"{name}: must be finite")
        if not self.wobble_period > 0:
            raise ValueError("wobble_period: must be > 0")
        v = np.asarray(self.vertices, dtype=np.float64)
        if self.closed:
            v = np.vstack([v, v[:1]])
        seg = np.hypot(*np.diff(v, axis=0).T)
        keep = np.concatenate([[True], seg > 1e-9])
        self._v = v[keep]
        self._s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(self._v, axis=0).T))])
        self.length = float(self._s[-1])
        # heading at each vertex: direction of the chord through its neighbours, unwrapped
        v = self._v
        nxt = np.vstack([v[1:], v[-1:] if not self.closed else v[1:2]])
        prv = np.vstack([v[:1] if not self.closed else v[-2:-1], v[:-1]])
        d = nxt - prv
        self._heading = np.unwrap(np.arctan2(d[:, 1], d[:, 0]))

    def arc_length(self, t: np.ndarray) -> np.ndarray:
        """Arc length travelled at times `t` s (from `start`), m."""
        t = np.asarray(t, dtype=np.float64)
        w = 2 * np.pi / self.wobble_period
        # s(t) = ∫ v (1 + a sin(w τ)) dτ
        s = self.speed * (t + self.speed_wobble * (1 - np.cos(w * t)) / w)
        return self.start + s

    def pose(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(north, east, heading) at times `t` (arrays shaped like `t`); m, m, rad."""
        s = self.arc_length(t)
        s = np.mod(s, self.length) if self.closed else np.clip(s, 0.0, self.length)
        i = np.clip(np.searchsorted(self._s, s, side="right") - 1, 0, len(self._s) - 2)
        a, b = self._v[i], self._v[i + 1]
        f = ((s - self._s[i]) / (self._s[i + 1] - self._s[i]))[..., None]
        p = a + f * (b - a)
        heading = np.mod(np.interp(s, self._s, self._heading), 2 * np.pi)
        return p[..., 0], p[..., 1], heading


@dataclass
class Waves:
    """Roll, pitch (rad) and heave (m, up) of the USV: sums of sines of harbour chop.

    amplitudes (3, m) and periods (3, m) per axis (roll, pitch, heave), phases (3, m) rad.
    """

    amplitudes: np.ndarray
    periods: np.ndarray
    phases: np.ndarray

    @classmethod
    def random(
        cls, rng: np.random.Generator, roll_deg: float = 2.5, pitch_deg: float = 1.5
    ) -> Waves:
        """Three components per axis with periods 2–6 s; the amplitudes sum to about
        `roll_deg` / `pitch_deg` (peak) and 3 cm of heave."""
        m = 3
        share = rng.dirichlet(np.ones(m), size=3)
        peak = np.array([np.radians(roll_deg), np.radians(pitch_deg), 0.03])
        amplitudes = share * peak[:, None]
        periods = rng.uniform(2.0, 6.0, size=(3, m))
        phases = rng.uniform(0.0, 2 * np.pi, size=(3, m))
        return cls(amplitudes, periods, phases)

    def at(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(roll rad, pitch rad, heave m) at times `t` s."""
        t = np.asarray(t, dtype=np.float64)[..., None, None]
        w = 2 * np.pi / self.periods
        v = (self.amplitudes * np.sin(w * t + self.phases)).sum(axis=-1)
        return v[..., 0], v[..., 1], v[..., 2]

    def rates(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(roll rate, pitch rate) rad/s at times `t` s (the derivative of `at`)."""
        t = np.asarray(t, dtype=np.float64)[..., None, None]
        w = 2 * np.pi / self.periods
        v = (self.amplitudes * w * np.cos(w * t + self.phases)).sum(axis=-1)
        return v[..., 0], v[..., 1]


@dataclass
class DriftMotion:
    """A floating object's drift: positions sampled every `dt` s from t = 0 (linearly
    interpolated between samples; held after the last one)."""

    north: np.ndarray
    east: np.ndarray
    yaw: np.ndarray
    dt: float

    @classmethod
    def simulate(
        cls,
        rng: np.random.Generator,
        start: tuple[float, float],
        duration: float,
        *,
        current: np.ndarray,
        windage: np.ndarray,
        sigma: float = 0.02,
        tau: float = 20.0,
        yaw0: float = 0.0,
        yaw_rate: float = 0.0,
        allowed: Callable[[np.ndarray], bool] | None = None,
        dt: float = 0.1,
    ) -> DriftMotion:
        """Integrate current + windage + an Ornstein–Uhlenbeck velocity (std `sigma` m/s,
        correlation time `tau` s). An object whose next position is not `allowed` (too near
        a wall or a boat) stops there."""
        n = round(duration / dt) + 2
        pos = np.empty((n, 2))
        pos[0] = start
        u = np.zeros(2)
        a = np.exp(-dt / tau)
        noise = rng.normal(0.0, sigma * np.sqrt(1 - a * a), size=(n, 2))
        stopped = False
        for k in range(1, n):
            u = a * u + noise[k]
            step = (np.asarray(current) + np.asarray(windage) + u) * dt
            nxt = pos[k - 1] + (0.0 if stopped else step)
            if not stopped and allowed is not None and not allowed(nxt):
                stopped, nxt = True, pos[k - 1]
            pos[k] = nxt
        yaw = yaw0 + yaw_rate * dt * np.arange(n)
        return cls(pos[:, 0], pos[:, 1], yaw, dt)

    def pose(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(north, east, yaw) at times `t` s; m, m, rad."""
        t = np.asarray(t, dtype=np.float64)
        grid = np.arange(self.north.size) * self.dt
        return (
            np.interp(t, grid, self.north),
            np.interp(t, grid, self.east),
            np.interp(t, grid, self.yaw),
        )


def point_segment_distance(p: np.ndarray, polyline: np.ndarray) -> float:
    """Smallest distance (m) from point `p` (2,) to a polyline (k, 2)."""
    p = as_float_array("p", p)
    polyline = as_float_array("polyline", polyline, ndim=2)
    if p.shape != (2,) or polyline.shape[1:] != (2,) or len(polyline) < 2:
        raise ValueError(
            f"p, polyline: expected (2,) and (k >= 2, 2), got {p.shape}, {polyline.shape}"
        )
    from usvfast.lidar.lines import point_segment_distance as distances

    return float(distances(p[None], np.hstack([polyline[:-1], polyline[1:]])).min())
