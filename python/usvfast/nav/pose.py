"""Vessel pose over time: position and attitude channels, each with its own time stamps and
clock offset, queried at arbitrary times.

Position (lat, lon, altitude) is interpolated linearly (longitude along the shorter way round
the antimeridian); angles (heading, roll, pitch) along the shortest arc. A query between two
samples more than `max_gap` seconds apart, or outside a channel's span, is an error
(PoseGapError), not a guess.

Example::

    from usvfast.nav.nmea import read_nmea
    from usvfast.nav.pose import PoseTrack
    track = PoseTrack.from_nmea(read_nmea("saab-r4.log"), max_gap=2.0)
    pose = track.at([1306933631.5, 1306933632.0])
    pose.lat_deg, pose.heading
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from usvfast._angles import wrap_2pi, wrap_180_deg, wrap_pi
from usvfast._core import DimensionError, TimeOrderError
from usvfast._validate import as_float_array

__all__ = ["Channel", "Pose", "PoseGapError", "PoseTrack"]


class PoseGapError(ValueError):
    """A pose was asked for at a time no sample covers (outside the span or in a long gap)."""


@dataclass(frozen=True)
class Channel:
    """One time series: `time` (n,) UNIX s in the stream's own clock, `values` (n, k), `kind`
    per column ("linear", "lon_deg" or "angle"), `clock_offset` seconds added to `time` to
    reach the reference clock, `max_gap` seconds."""

    time: np.ndarray
    values: np.ndarray
    kinds: tuple[str, ...]
    clock_offset: float
    max_gap: float
    name: str

    @classmethod
    def build(
        cls,
        name: str,
        time: Any,
        columns: dict[str, Any],
        kinds: tuple[str, ...],
        clock_offset: float,
        max_gap: float,
        time_name: str | None = None,
    ) -> Channel:
        """Validate and build; samples with any non-finite value are dropped, exact duplicate
        times keep the first sample. Errors name `time_name` (default `<name>_time`) and the
        column keys. Raises TimeOrderError when times go backwards, DimensionError on shapes,
        TypeError on non-numbers, ValueError when no finite sample is left."""
        time_name = f"{name}_time" if time_name is None else time_name
        t = as_float_array(time_name, time, ndim=1)
        cols = []
        for col_name, col in columns.items():
            a = as_float_array(col_name, col, finite=False).reshape(-1)
            if a.shape != t.shape:
                raise DimensionError(f"{col_name}: expected shape {t.shape}, got {a.shape}")
            cols.append(a)
        v = np.stack(cols, axis=1) if cols else np.empty((t.size, 0))
        if np.any(np.diff(t) < 0):
            i = int(np.argmax(np.diff(t) < 0))
            raise TimeOrderError(
                f"{time_name}: must be sorted ascending, element {i + 1} ({t[i + 1]}) is "
                f"before element {i} ({t[i]})"
            )
        keep = np.all(np.isfinite(v), axis=1)
        keep[1:] &= np.diff(t) > 0
        if not np.any(keep):
            raise ValueError(f"{name}: no finite sample")
        if not max_gap > 0:
            raise ValueError(f"max_gap: must be positive, got {max_gap}")
        return cls(
            t[keep] + clock_offset, v[keep], kinds, float(clock_offset), float(max_gap), name
        )

    def _bracket(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Indices (i, j) of the samples around each time and whether the time is covered."""
        ts = self.time
        i = np.clip(np.searchsorted(ts, t, side="right") - 1, 0, len(ts) - 1)
        j = np.minimum(i + 1, len(ts) - 1)
        before, after = t - ts[i], ts[j] - t
        # Exactly on a sample, or between two samples at most max_gap apart.
        exact = before == 0
        inside = (before >= 0) & (after >= 0) & (j > i)
        return i, j, exact | (inside & (ts[j] - ts[i] <= self.max_gap))

    def covered(self, t: np.ndarray) -> np.ndarray:
        """Boolean (m,): which reference times `t` (m,) `at` can answer."""
        return self._bracket(t)[2]

    def at(self, t: np.ndarray) -> np.ndarray:
        """Values (m, k) at reference times `t` (m,); raises PoseGapError naming the first bad
        time."""
        ts, v = self.time, self.values
        i, j, ok = self._bracket(t)
        if not np.all(ok):
            k = int(np.argmin(ok))
            raise PoseGapError(
                f"times: {t[k]!r} is not covered by {self.name} (samples from {ts[0]!r} to "
                f"{ts[-1]!r}, max_gap {self.max_gap} s)"
            )
        span = np.where(j > i, ts[j] - ts[i], 1.0)
        f = np.where(j > i, (t - ts[i]) / span, 0.0)[:, None]
        d = v[j] - v[i]
        for c, kind in enumerate(self.kinds):
            if kind == "angle":  # shortest arc, radians
                d[:, c] = wrap_pi(d[:, c])
            elif kind == "lon_deg":
                d[:, c] = wrap_180_deg(d[:, c])
        out = v[i] + f * d
        for c, kind in enumerate(self.kinds):
            if kind == "lon_deg":
                out[:, c] = wrap_180_deg(out[:, c])
        return out


@dataclass(frozen=True)
class Pose:
    """Poses at query times, shape (m,) each: lat_deg, lon_deg, altitude (m, NaN if unknown),
    heading in [0, 2π) (clockwise from true north), roll and pitch in [-π, π) (NaN when the
    track has no such channel)."""

    time: np.ndarray
    lat_deg: np.ndarray
    lon_deg: np.ndarray
    altitude: np.ndarray
    heading: np.ndarray
    roll: np.ndarray
    pitch: np.ndarray


class PoseTrack:
    """A vessel pose track: a position channel plus optional heading and roll/pitch channels,
    each with its own times, clock offset and maximum gap (seconds)."""

    def __init__(
        self,
        position_time: Any,
        lat_deg: Any,
        lon_deg: Any,
        altitude: Any = None,
        *,
        heading_time: Any = None,
        heading: Any = None,
        attitude_time: Any = None,
        roll: Any = None,
        pitch: Any = None,
        max_gap: float = 2.0,
        position_offset: float = 0.0,
        heading_offset: float = 0.0,
        attitude_offset: float = 0.0,
    ) -> None:
        """position_time (n,), lat_deg, lon_deg (n,), altitude (n,) or None; heading (radians)
        at heading_time; roll, pitch (radians) at attitude_time. `*_offset` seconds are added to
        each stream's times (per-stream clock offsets). Altitude is its own channel on the
        position times: samples without altitude keep their position, and a query the altitude
        samples do not cover gets a NaN altitude."""
        self.position = Channel.build(
            "position",
            position_time,
            {"lat_deg": lat_deg, "lon_deg": lon_deg},
            ("linear", "lon_deg"),
            position_offset,
            max_gap,
        )
        self.altitude = None
        if altitude is not None:
            self.altitude = Channel.build(
                "altitude",
                position_time,
                {"altitude": altitude},
                ("linear",),
                position_offset,
                max_gap,
                time_name="position_time",
            )
        self.has_altitude = self.altitude is not None
        self.heading = None
        if heading is not None:
            self.heading = Channel.build(
                "heading", heading_time, {"heading": heading}, ("angle",), heading_offset, max_gap
            )
        self.attitude = None
        if roll is not None or pitch is not None:
            if roll is None or pitch is None:
                raise ValueError("roll, pitch: give both or neither")
            self.attitude = Channel.build(
                "attitude",
                attitude_time,
                {"roll": roll, "pitch": pitch},
                ("angle", "angle"),
                attitude_offset,
                max_gap,
            )

    @classmethod
    def from_nmea(
        cls,
        log: Any,
        *,
        max_gap: float = 2.0,
        position_offset: float = 0.0,
        heading_offset: float = 0.0,
    ) -> PoseTrack:
        """From a `read_nmea` result: positions with a fix (quality > 0) and true headings
        (HDT/THS); altitude from the fixes that have one (none: NaN altitude). Raises
        ValueError when there is no fix."""
        p = log.positions
        fix = (p.fix_quality > 0) & np.isfinite(p.lat_deg) & np.isfinite(p.lon_deg)
        if not np.any(fix):
            raise ValueError("log: no position with a fix")
        alt = p.altitude[fix]
        h = log.headings
        order = np.argsort(h.time, kind="stable")
        return cls(
            p.time[fix],
            p.lat_deg[fix],
            p.lon_deg[fix],
            alt if np.any(np.isfinite(alt)) else None,
            heading_time=h.time[order] if len(h.time) else None,
            heading=np.radians(h.heading_deg[order]) if len(h.time) else None,
            max_gap=max_gap,
            position_offset=position_offset,
            heading_offset=heading_offset,
        )

    def at(self, times: ArrayLike) -> Pose:
        """Pose at reference times (UNIX s, (m,) or scalar). Raises PoseGapError when any
        channel present does not cover a time."""
        t = as_float_array("times", times).reshape(-1)
        pos = self.position.at(t)
        nan = np.full(t.shape, np.nan)
        altitude = nan
        if self.altitude is not None:
            altitude = nan.copy()
            ok = self.altitude.covered(t)
            altitude[ok] = self.altitude.at(t[ok])[:, 0]
        heading = wrap_2pi(self.heading.at(t)[:, 0]) if self.heading is not None else nan
        if self.attitude is not None:
            att = wrap_pi(self.attitude.at(t))
            roll, pitch = att[:, 0], att[:, 1]
        else:
            roll = pitch = nan
        return Pose(
            time=t,
            lat_deg=pos[:, 0],
            lon_deg=pos[:, 1],
            altitude=altitude,
            heading=heading,
            roll=roll,
            pitch=pitch,
        )
