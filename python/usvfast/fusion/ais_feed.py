"""AIS feeds as logs deliver them, and AIS targets as tracks in a local NED plane.

`read_ais_feed` decodes the feed with `usvfast.nav.ais.read_ais` (pyais; multi-sentence
messages assembled, damaged sentences counted), which gives every AIS line its receive time
(NMEA 4.10 tag block `c:`, a leading UNIX time column, or the log's own ZDA/RMC clock; see
`usvfast.nav.linetime`), and requires timed positions. `AisTargets` turns the position
reports into per-MMSI states at any time by the constant speed and course interpolation of
the radar/AIS paper (§1.1), reusing `usvfast.nav.ais.dead_reckon`, with a covariance that
grows with the age of the report.

Example::

    feed = read_ais_feed("feed.nmea")
    targets = AisTargets(feed, origin=(63.43, 10.39))
    st = targets.states_at(t)       # st.mmsi (m,), st.state (m, 4) [n, v_n, e, v_e], st.cov
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterable
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from usvfast import geodesy
from usvfast._validate import as_float_array, instance
from usvfast.nav.ais import AisLog, AisPositions, dead_reckon, read_ais

__all__ = ["AisFeed", "AisStates", "AisTargets", "fix_times", "read_ais_feed"]


@dataclass(frozen=True)
class AisFeed:
    """A decoded AIS feed: `log` (positions with receive times, static data by MMSI, the
    reader's counts), n_untimed (position reports with no receive time, not usable),
    n_bad_tag (lines with a wrong tag-block checksum, skipped), n_clock (ZDA/RMC sentences that
    set the log clock)."""

    log: AisLog
    n_untimed: int
    n_bad_tag: int
    n_clock: int

    @property
    def names(self) -> dict[int, str]:
        """Vessel names by MMSI (static reports; only MMSIs with a name)."""
        return {m: s.name for m, s in self.log.static.items() if s.name}


def read_ais_feed(source: str | os.PathLike | Iterable[Any]) -> AisFeed:
    """Read an AIS feed (a path or lines) with receive times; see the module docstring.

    Raises ValueError when nothing decodes, and when no position report has both a receive
    time and a position (an AIS feed without positions cannot be fused)."""
    log = read_ais(source)
    p = log.positions
    timed = np.isfinite(p.time)
    usable = timed & np.isfinite(p.lat_deg) & np.isfinite(p.lon_deg)
    if not np.any(usable):
        raise ValueError(
            f"source: no AIS position report with a receive time and a position "
            f"({len(p.time)} position reports, {int(timed.sum())} timed, "
            f"{log.n_messages} messages); receive times come from tag blocks (c:), a leading "
            "UNIX time column or the log's ZDA/RMC sentences"
        )
    return AisFeed(log, int((~timed).sum()), log.n_bad_tag, log.n_clock)


def fix_times(positions: AisPositions) -> AisPositions:
    """Position reports timed by their fix: the latest whole second at or before the receive
    time whose UTC second equals the report's `second` field (AIS sends only that second;
    whole-second receive stamps may lag the fix by up to 1 s, transmission slots by a few).
    Reports with second >= 60 (not available) keep their receive time."""
    instance("positions", positions, AisPositions)
    t_rx = positions.time
    sec = positions.second
    ok = np.isfinite(t_rx) & (sec < 60)
    stamp = np.floor(np.where(ok, t_rx, 0.0))
    t_fix = stamp - np.mod(np.mod(stamp, 60.0) - sec, 60.0)
    return replace(positions, time=np.where(ok, t_fix, t_rx))


@dataclass(frozen=True)
class AisStates:
    """AIS targets at one time: mmsi (m,), state (m, 4) [n, v_n, e, v_e] (m, m/s, NED of the
    plane), cov (m, 4, 4), age (m,) seconds since the report used, lat_deg, lon_deg (m,)."""

    mmsi: np.ndarray
    state: np.ndarray
    cov: np.ndarray
    age: np.ndarray
    lat_deg: np.ndarray
    lon_deg: np.ndarray


class AisTargets:
    """Per-MMSI AIS tracks in the NED plane at `origin` (lat, lon degrees, height 0).

    Positions at time t by dead reckoning from the latest report at or before t (paper §1.1);
    velocity from that report's speed and course over ground. Covariance of a report of age a
    (s): a constant-velocity prediction of diag(σ_p², σ_v²) per axis with white acceleration
    of spectral density `accel_psd` (m²/s³): P_pp = σ_p² + a²σ_v² + q a³/3, P_pv = a σ_v² +
    q a²/2, P_vv = σ_v² + q a. Defaults: σ_p = `pos_std` 5 m (GNSS of a class A transponder
    and its antenna offset), σ_v = `vel_std` 0.3 m/s (0.1 kn and 0.1° quantisation and
    GNSS speed noise), q = 0.5 (a manoeuvring small craft). Reports older than `max_age`
    (s, default 120) are not used. Own-ship reports (!AIVDO) are left out. use_second: time
    each report by its UTC second field (`fix_times`) rather than its receive time."""

    def __init__(
        self,
        feed: AisFeed,
        origin: tuple[float, float],
        *,
        pos_std: float = 5.0,
        vel_std: float = 0.3,
        accel_psd: float = 0.5,
        max_age: float = 120.0,
        use_second: bool = True,
    ) -> None:
        instance("feed", feed, AisFeed)
        o = as_float_array("origin", origin, ndim=1)
        if o.shape != (2,) or abs(o[0]) > 90:
            raise ValueError(f"origin: expected (lat deg in [-90, 90], lon deg), got {origin!r}")
        for name, v in (("pos_std", pos_std), ("vel_std", vel_std), ("max_age", max_age)):
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"{name}: must be finite and > 0, got {v!r}")
        if not (math.isfinite(accel_psd) and accel_psd >= 0):
            raise ValueError(f"accel_psd: must be finite and >= 0, got {accel_psd!r}")
        self.positions = fix_times(feed.log.positions) if use_second else feed.log.positions
        self.names = feed.names
        self.origin = (float(origin[0]), float(origin[1]))
        self.pos_std, self.vel_std, self.accel_psd, self.max_age = (
            pos_std,
            vel_std,
            accel_psd,
            max_age,
        )
        p = self.positions
        usable = np.isfinite(p.time) & np.isfinite(p.lat_deg) & np.isfinite(p.lon_deg) & ~p.own_ship
        self.mmsis = np.unique(p.mmsi[usable])
        self._reports: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        for m in self.mmsis.tolist():
            sel = np.flatnonzero(usable & (p.mmsi == m))
            sel = sel[np.argsort(p.time[sel], kind="stable")]
            spd = np.where(np.isfinite(p.speed[sel]), p.speed[sel], 0.0)
            crs = np.radians(np.where(np.isfinite(p.course_deg[sel]), p.course_deg[sel], 0.0))
            moving = np.isfinite(p.speed[sel]) & np.isfinite(p.course_deg[sel])
            vel = np.where(moving[:, None], np.stack([spd * np.cos(crs), spd * np.sin(crs)], 1), 0)
            self._reports[m] = (p.time[sel], vel)

    def report_times(self, mmsi: int) -> np.ndarray:
        """Receive times (UNIX s) of the usable position reports of `mmsi`."""
        return self._reports[int(mmsi)][0]

    def states_at(self, t: float) -> AisStates:
        """The AIS targets with a report at most `max_age` old at time `t` (UNIX s)."""
        rows = []
        for m in self.mmsis.tolist():
            t_rep, vel = self._reports[m]
            i = int(np.searchsorted(t_rep, t, side="right")) - 1
            if i < 0 or t - t_rep[i] > self.max_age:
                continue
            lat, lon, age = dead_reckon(self.positions, m, np.array([t]))
            rows.append((m, float(lat[0]), float(lon[0]), float(age[0]), vel[i]))
        n = len(rows)
        if n == 0:
            z = np.zeros(0)
            return AisStates(z.astype(np.int64), np.zeros((0, 4)), np.zeros((0, 4, 4)), z, z, z)
        mmsi = np.array([r[0] for r in rows], dtype=np.int64)
        lat = np.array([r[1] for r in rows])
        lon = np.array([r[2] for r in rows])
        age = np.array([r[3] for r in rows])
        vel = np.array([r[4] for r in rows])
        north, east, _ = geodesy.geodetic2ned(lat, lon, 0.0, self.origin[0], self.origin[1], 0.0)
        state = np.stack([north, vel[:, 0], east, vel[:, 1]], axis=1)
        return AisStates(mmsi, state, self.covariance(age), age, lat, lon)

    def covariance(self, age: ArrayLike) -> np.ndarray:
        """AIS state covariance (m, 4, 4) for report ages (m,) seconds (see the class)."""
        a = np.asarray(age, dtype=float)
        sp2, sv2, q = self.pos_std**2, self.vel_std**2, self.accel_psd
        block = np.empty((len(a), 2, 2))
        block[:, 0, 0] = sp2 + a * a * sv2 + q * a**3 / 3.0
        block[:, 0, 1] = block[:, 1, 0] = a * sv2 + q * a * a / 2.0
        block[:, 1, 1] = sv2 + q * a
        cov = np.zeros((len(a), 4, 4))
        cov[:, :2, :2] = block
        cov[:, 2:, 2:] = block
        return cov
