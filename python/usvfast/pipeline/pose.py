"""The vessel pose at each sensor timestamp: GNSS position and heading (with the antenna's
lever arm removed), roll and pitch from an IMU or NMEA attitude sentences (PASHR, XDR), in
the local NED frame at the origin.

Two sources share one result type, `VesselPose`:
- `NavTrack.from_config` reads the navigation and attitude streams of a recording once (small
  arrays: 10 Hz for an hour is 36,000 samples) and interpolates them at any time, as
  `usvfast.nav.pose` does (linear in NED metres, shortest arc for angles, refusing gaps longer
  than `recording.max_pose_gap`);
- `usvfast.pipeline.live_pose.LivePose` follows the navigation messages as they arrive
  (`pipeline.process`) and answers from the newest samples (interpolated when bracketed, else
  extrapolated from the last two, at most max_gap ahead).

Each pose carries the navigation's errors (`NavErrors`: the fixes' std by their GGA quality,
the interpolation's), which `VesselPose.covariance_at` turns into the covariance they add to a
detection. IMU orientation follows ROS REP-103 (`usvfast.pipeline.orientation`). The attitude
stream's yaw is not used: heading comes from the navigation streams, as NMEA HDT/THS sentences
(or a GNSS compass's PSAT,HPR / PASHR,HPR / PTNL,AVR, `usvfast.nav.nmea`) or as orientations
from a dual-antenna GNSS (`geometry_msgs/QuaternionStamped` or `sensor_msgs/Imu` topics;
`quaternion_heading`), whose yaw follows the stream option `yaw_convention`: "enu" (REP-103,
the default: the body's x axis from east, counter-clockwise) or "north_clockwise" (the yaw is
the heading itself, as nmea_navsat_driver publishes HDT on its `heading` topic).
"""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from usvfast import geodesy
from usvfast._core import DimensionError
from usvfast._validate import as_float_array
from usvfast.nav.pose import Channel, PoseGapError
from usvfast.pipeline.gyro_bridge import bridge_heading_gaps, heading_rates
from usvfast.pipeline.orientation import (
    HEADING_MSGTYPES,
    YAW_CONVENTIONS,
    imu_roll_pitch,
    quaternion_heading,
    usable_orientations,
)

__all__ = [
    "NavErrors",
    "NavTrack",
    "NavigationError",
    "VesselPose",
    "yaw_convention",
]


class NavigationError(ValueError):
    """The recording has no usable navigation (GNSS position or heading); the message names
    the stream and what is missing."""


@dataclass(frozen=True)
class VesselPose:
    """The vessel reference point at `time` (UNIX s): north, east (m, NED at the origin),
    heading (rad clockwise from north), roll, pitch (rad, FRD; 0 without attitude)."""

    time: float
    north: float
    east: float
    heading: float
    roll: float = 0.0
    pitch: float = 0.0
    #: Variance of north and east (each, m²) and of the heading (rad²) from `NavErrors`.
    position_var: float = 0.0
    heading_var: float = 0.0

    @property
    def planar(self) -> np.ndarray:
        """(north, east, heading) as the LiDAR detector takes it."""
        return np.array([self.north, self.east, self.heading])

    def covariance_at(self, positions: ArrayLike) -> np.ndarray | None:
        """(k, 2, 2) NED covariance (m²) that this pose's errors add to detections at
        `positions` (k, 2) north, east m: `position_var` on both axes, and the heading's
        `heading_var` × range² across each line of sight from the reference point. None when
        the pose has no error (nothing to add)."""
        z = as_float_array("positions", positions, ndim=2)
        if z.shape[1] != 2:
            raise DimensionError(f"positions: expected shape (k, 2), got {z.shape}")
        if self.position_var == 0.0 and self.heading_var == 0.0:
            return None
        r = z - (self.north, self.east)
        across = np.stack([-r[:, 1], r[:, 0]], axis=1)  # ⊥ line of sight, length = range
        cov = self.heading_var * across[:, :, None] * across[:, None, :]
        cov[:, 0, 0] += self.position_var
        cov[:, 1, 1] += self.position_var
        return cov


@dataclass(frozen=True)
class NavErrors:
    """The navigation's errors that reach every detection (a detection is the vessel's pose
    plus a rotated offset; `VesselPose.covariance_at`).

    fix_std: {GGA fix quality: horizontal std per axis, m} beyond what the sensors'
    measurement models already hold (a quality not listed adds nothing): e.g. {5: 0.1} for
    RTK float when the models were calibrated under RTK fixed (4), from the receiver's data
    sheet. acceleration_std (m/s²) and heading_acceleration_std (rad/s²): the vessel's
    unmodelled accelerations; linear interpolation between samples τ and T − τ s away misses
    a constant acceleration a by a/2 · τ (T − τ), which is small between 10 Hz samples and
    grows in a gap of the navigation.
    """

    fix_std: dict[int, float] = field(default_factory=dict)
    acceleration_std: float = 0.0
    heading_acceleration_std: float = 0.0

    def __post_init__(self) -> None:
        for quality, std in self.fix_std.items():
            if not (isinstance(quality, int) and 0 <= std < math.inf):
                raise ValueError(
                    f"fix_std: expected {{GGA fix quality (int): std m >= 0}}, got "
                    f"{quality!r}: {std!r}"
                )
        for name in ("acceleration_std", "heading_acceleration_std"):
            if not 0 <= getattr(self, name) < math.inf:
                raise ValueError(f"{name}: must be finite and >= 0, got {getattr(self, name)}")

    def std_of(self, quality: ArrayLike) -> np.ndarray:
        """Horizontal std (m) of fixes of GGA `quality` (n,); 0 for an unlisted quality."""
        q = np.asarray(quality).reshape(-1)
        return np.array([self.fix_std.get(int(k), 0.0) for k in q], dtype=np.float64)

    def position_var(self, fix_std: float, spread: float) -> float:
        """Variance (m²) of a position interpolated from fixes of std `fix_std` (m) with
        `spread` = |τ (T − τ)| (s²)."""
        return fix_std**2 + (0.5 * self.acceleration_std * spread) ** 2

    def heading_var(self, spread: float) -> float:
        """Variance (rad²) of a heading interpolated with `spread` = |τ (T − τ)| (s²)."""
        return (0.5 * self.heading_acceleration_std * spread) ** 2


def _lever_ne(lever: np.ndarray, heading: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    c, s = np.cos(heading), np.sin(heading)
    return c * lever[0] - s * lever[1], s * lever[0] + c * lever[1]


class NavTrack:
    """Interpolated vessel pose from a recording's navigation and attitude streams.

    position (NED m of the vessel reference point), heading and optional attitude channels;
    `origin` (lat, lon, h) of the NED frame; `damaged` {stream id: skipped records};
    `errors` the navigation's errors given to each pose, with `fix_std` (times UNIX s,
    horizontal std m) of the fixes by their quality (None: no fix std).
    """

    def __init__(
        self,
        origin: tuple[float, float, float],
        position: Channel,
        heading: Channel,
        attitude: Channel | None,
        damaged: dict[str, int],
        errors: NavErrors | None = None,
        fix_std: tuple[np.ndarray, np.ndarray] | None = None,
    ) -> None:
        self.origin = origin
        self.errors = NavErrors() if errors is None else errors
        self.fix_std = fix_std
        self._fix_std = None
        if fix_std is not None:
            self._fix_std = (np.asarray(fix_std[0]).tolist(), np.asarray(fix_std[1])[:, None])
        self.position = position
        self.heading = heading
        self.attitude = attitude
        self.damaged = damaged
        self._pos = (position.time.tolist(), position.values)
        self._head = (heading.time.tolist(), heading.values)
        self._att = None if attitude is None else (attitude.time.tolist(), attitude.values)
        self.start = float(max(position.time[0], heading.time[0]))
        self.end = float(min(position.time[-1], heading.time[-1]))
        #: The correction added to the navigation's headings, degrees clockwise.
        self.heading_offset_deg = 0.0
        self._source: _NavSource | None = None

    @classmethod
    def from_config(cls, config: Any) -> NavTrack:
        """Read the config's navigation streams (NMEA text `nmea`; bag topics of
        nmea_msgs/Sentence or NavSatFix) and attitude stream (bag sensor_msgs/Imu), the
        headings corrected by the config's `heading_offset_deg`. Raises NavigationError
        naming the stream when no position fix or no heading is found."""
        fixes: list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]] = []
        headings: list[tuple[np.ndarray, np.ndarray]] = []
        damaged: dict[str, int] = {}
        lever = np.zeros(3)
        for sid in config.navigation:
            spec = config.recording.stream(sid)
            if spec.mount is not None:
                lever = np.asarray(spec.mount.lever_arm, dtype=np.float64)
            t_fix, lat, lon, quality, t_head, head, bad = _read_nav(spec)
            damaged[sid] = bad
            if t_fix.size:
                fixes.append((t_fix + spec.clock_offset, lat, lon, quality))
            if t_head.size:
                headings.append((t_head + spec.clock_offset, head))
        names = ", ".join(repr(s) for s in config.navigation)
        if not fixes:
            raise NavigationError(
                f"recording {config.recording.name!r}: no GNSS position fix in the navigation "
                f"stream(s) {names}"
            )
        if not headings:
            raise NavigationError(
                f"recording {config.recording.name!r}: no heading (NMEA HDT/THS/HPR/AVR, or a "
                f"QuaternionStamped / Imu topic) in the navigation stream(s) {names}"
            )
        t_fix, lat, lon, quality = fixes[0]
        lat0, lon0, h0 = config.origin or (float(lat[0]), float(lon[0]), 0.0)
        n, e, _ = geodesy.geodetic2ned(lat, lon, np.zeros_like(lat), lat0, lon0, h0)
        t_head, head = headings[0]
        order = np.argsort(t_head, kind="stable")
        t_head, head = t_head[order], head[order]
        gap = config.recording.max_pose_gap
        attitude = rates = None
        if config.attitude is not None:
            spec = config.recording.stream(config.attitude)
            t_att, roll, pitch, bad, rates = _read_attitude(spec, float(t_fix[0]))
            # A navigation stream read again for its attitude: its reader already counted
            # every damaged line.
            damaged[spec.id] = max(damaged.get(spec.id, 0), bad)
            attitude = Channel.build(
                "attitude",
                t_att + spec.clock_offset,
                {"roll": roll, "pitch": pitch},
                ("angle", "angle"),
                0.0,
                gap,
            )
            if rates is not None:
                rates = (rates[0] + spec.clock_offset, rates[1])
        if config.gyro_heading_bridge:
            if rates is None:
                raise NavigationError(
                    f"recording {config.recording.name!r}: gyro_heading_bridge needs an "
                    "attitude stream of sensor_msgs/Imu (its gyro carries the heading)"
                )
            steps = np.diff(t_head)
            steps = steps[steps > 0]  # a gap: 3 of the headings' usual intervals
            min_gap = 3.0 * float(np.median(steps)) if steps.size else gap
            t_head, head = bridge_heading_gaps(t_head, head, *rates, min_gap)
        source = _NavSource(t_fix, n, e, t_head, head, lever, gap)
        position, heading = source.channels(math.radians(config.heading_offset_deg))
        if not np.any(heading.covered(t_fix)):
            raise NavigationError(
                f"recording {config.recording.name!r}: headings of {names} do not overlap the "
                "position fixes in time"
            )
        errors = config.nav_errors
        fix_std = (t_fix, errors.std_of(quality)) if errors.fix_std else None
        track = cls((lat0, lon0, h0), position, heading, attitude, damaged, errors, fix_std)
        track._source = source
        track.heading_offset_deg = float(config.heading_offset_deg)
        return track

    def with_heading_offset(self, offset_deg: float) -> NavTrack:
        """A copy whose headings are the navigation's plus `offset_deg` (degrees clockwise,
        in all: it replaces any offset applied before), the antenna's lever arm removed again
        with them. Only for a NavTrack read by `from_config`."""
        if self._source is None:
            raise ValueError("offset_deg: this NavTrack was not read by NavTrack.from_config")
        position, heading = self._source.channels(math.radians(offset_deg))
        track = NavTrack(
            self.origin, position, heading, self.attitude, self.damaged, self.errors, self.fix_std
        )
        track._source = self._source
        track.heading_offset_deg = float(offset_deg)
        return track

    def pose_at(self, t: float) -> VesselPose | None:
        """The pose at UNIX time t, or None when the GNSS does not cover t (a gap). Without
        attitude samples around t, roll and pitch are 0."""
        ne = _interp(self._pos, t, self.position.max_gap, False)
        h = _interp(self._head, t, self.heading.max_gap, True)
        if ne is None or h is None:
            return None
        roll = pitch = 0.0
        if self._att is not None:
            att = _interp(self._att, t, self.attitude.max_gap, True)  # type: ignore[union-attr]
            if att is not None:
                roll, pitch = float(att[0]), float(att[1])
        std = None if self._fix_std is None else _interp(self._fix_std, t, math.inf, False)
        position_var = self.errors.position_var(
            0.0 if std is None else float(std[0]), _spread(self._pos[0], t)
        )
        heading_var = self.errors.heading_var(_spread(self._head[0], t))
        return VesselPose(
            float(t),
            float(ne[0]),
            float(ne[1]),
            float(h[0]) % (2 * math.pi),
            roll,
            pitch,
            position_var,
            heading_var,
        )


@dataclass(frozen=True)
class _NavSource:
    """The navigation as read (antenna fixes in NED m, headings rad in time order), from
    which the position and heading channels are built for a heading correction."""

    t_fix: np.ndarray
    north: np.ndarray
    east: np.ndarray
    t_head: np.ndarray
    head: np.ndarray
    lever: np.ndarray
    max_gap: float

    def channels(self, offset: float) -> tuple[Channel, Channel]:
        """(position, heading) with `offset` rad added to the headings: the reference
        point's position is the antenna's minus the heading-rotated lever arm."""
        heading = Channel.build(
            "heading", self.t_head, {"heading": self.head + offset}, ("angle",), 0.0, self.max_gap
        )
        h_at_fix = np.full(self.t_fix.shape, np.nan)
        ok = heading.covered(self.t_fix)
        h_at_fix[ok] = heading.at(self.t_fix[ok])[:, 0]
        dn, de = _lever_ne(self.lever, h_at_fix)
        position = Channel.build(
            "position",
            self.t_fix,
            {"north": self.north - dn, "east": self.east - de},
            ("linear", "linear"),
            0.0,
            self.max_gap,
        )
        return position, heading


def _spread(times: list[float], t: float) -> float:
    """τ (T − τ) (s²) of time t between the two samples of `times` around it (0 on a sample
    or outside them)."""
    j = bisect.bisect_right(times, t)
    if j == 0 or j == len(times):
        return 0.0
    return (t - times[j - 1]) * (times[j] - t)


def _interp(
    channel: tuple[list[float], np.ndarray], t: float, max_gap: float, angle: bool
) -> np.ndarray | None:
    """Channel.at for one time (same rule: exactly on a sample, or between two samples at
    most max_gap apart), without the array overhead."""
    times, values = channel
    j = bisect.bisect_right(times, t)
    if j == 0:
        return None
    i = j - 1
    if times[i] == t:
        return values[i]
    if j == len(times) or times[j] - times[i] > max_gap:
        return None
    f = (t - times[i]) / (times[j] - times[i])
    d = values[j] - values[i]
    if angle:
        d = (d + math.pi) % (2 * math.pi) - math.pi
    return values[i] + f * d


# fix times, lat, lon, fix quality (GGA; -1 unknown), heading times, headings rad, damaged
_Nav = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, int]


def yaw_convention(spec: Any) -> str:
    """The stream option `yaw_convention` of a navigation stream (default "enu"); a
    NavigationError naming the stream and the option for an unknown value."""
    value = spec.options.get("yaw_convention", "enu")
    if value not in YAW_CONVENTIONS:
        raise NavigationError(
            f"stream {spec.id!r}: option 'yaw_convention': expected one of {YAW_CONVENTIONS}, "
            f"got {value!r}"
        )
    return value


def _read_nav(spec: Any) -> _Nav:
    """(fix times, lat, lon, heading times, headings rad, damaged) of one navigation stream."""
    from usvfast.nav.nmea import read_nmea

    empty = np.zeros(0)
    try:
        if spec.type == "nmea":
            log, bad = read_nmea(spec.path), None
        elif spec.type == "bag":
            from usvfast.nav.bags import read_bag_navsatfix, read_bag_nmea
            from usvfast.pipeline.streams import check_topic

            msgtype = check_topic(
                spec.path,
                spec.topic,
                ["nmea_msgs/msg/Sentence", "sensor_msgs/msg/NavSatFix", *HEADING_MSGTYPES],
            )
            if msgtype in HEADING_MSGTYPES:
                from usvfast.nav.bags import read_bag_orientations

                t, q, bad = read_bag_orientations(spec.path, spec.topic)
                ok = _oriented(spec, q)
                t, q, unusable = t[ok], q[ok], int((~ok).sum())
                heading = quaternion_heading(q, yaw_convention(spec))
                return empty, empty, empty, empty, t, heading, bad + unusable
            if msgtype == "sensor_msgs/msg/NavSatFix":
                fix = read_bag_navsatfix(spec.path, spec.topic)
                ok = fix.status >= 0
                unknown = np.full(int(ok.sum()), -1)
                return (
                    *(fix.times[ok], fix.lat_deg[ok], fix.lon_deg[ok], unknown),
                    *(empty, empty, fix.skipped),
                )
            try:
                res = read_bag_nmea(spec.path, spec.topic)
            except ValueError:
                # No time of day in the topic (e.g. HDT only): the message stamps time it.
                return _stamped_nmea(spec)
            log, bad = res.log, res.skipped_messages
        else:
            raise NavigationError(
                f"stream {spec.id!r}: type {spec.type!r} cannot be a navigation stream (use "
                "nmea, or bag with nmea_msgs/Sentence, NavSatFix, QuaternionStamped or Imu)"
            )
    except NavigationError:
        raise
    except ValueError as exc:
        raise NavigationError(
            f"no GNSS position fix in the navigation stream {spec.id!r}: {exc}"
        ) from exc
    p = log.positions
    ok = (p.fix_quality > 0) & np.isfinite(p.lat_deg) & np.isfinite(p.lon_deg)
    h = log.headings
    damaged = int(log.n_damaged) + int(bad or 0)
    q = p.fix_quality[ok]
    return p.time[ok], p.lat_deg[ok], p.lon_deg[ok], q, h.time, np.radians(h.heading_deg), damaged


def _stamped_nmea(spec: Any) -> _Nav:
    """`_read_nav`'s result for a bag topic of nmea_msgs/Sentence timed by the message stamps
    (sentences through `parse_sentence`); damaged = messages or sentences that did not parse."""
    from usvfast.nav.bags import BagTopic
    from usvfast.pipeline.live_pose import parse_sentence

    reader = BagTopic(spec.path, spec.topic)
    fixes: list[tuple[float, float, float, float]] = []
    heads: list[tuple[float, float]] = []
    bad = 0
    for m in reader:
        parsed = parse_sentence(m.data) if isinstance(m.data, str) else None
        if parsed is None:
            bad += isinstance(m.data, str) and m.data.strip()[:1] in ("$", "!") and not _ok(m.data)
            continue
        kind, values = parsed
        if kind == "fix":
            fixes.append((float(m.time), values[0], values[1], values[2]))
        elif kind == "heading":
            heads.append((float(m.time), math.radians(values[0])))
    f = np.array(fixes, dtype=np.float64).reshape(-1, 4)
    h = np.array(heads, dtype=np.float64).reshape(-1, 2)
    return f[:, 0], f[:, 1], f[:, 2], f[:, 3], h[:, 0], h[:, 1], bad + reader.damaged


def _ok(sentence: str) -> bool:
    """Whether an NMEA sentence parses with a valid checksum (whatever its type)."""
    import pynmea2

    try:
        pynmea2.parse(sentence.strip(), check=True)
    except (pynmea2.ParseError, ValueError, AttributeError, TypeError):
        return False
    return True


def _oriented(spec: Any, q: np.ndarray) -> np.ndarray:
    """(n,) bool: which samples of a bag topic have a quaternion that is an orientation;
    NavigationError when none has (an IMU that publishes no orientation estimate)."""
    ok = usable_orientations(q)
    if not ok.any():
        raise NavigationError(
            f"stream {spec.id!r}: topic {spec.topic!r} carries no orientation in its "
            f"{len(q)} messages (zero or invalid quaternions: an IMU without an orientation "
            "estimate); use another topic for heading or attitude"
        )
    return ok


def _read_attitude(
    spec: Any, reference: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, int, tuple[np.ndarray, np.ndarray] | None]:
    """(times, roll rad, pitch rad, damaged, heading rates) of the attitude stream: a bag topic
    of sensor_msgs/Imu or nmea_msgs/Sentence, or an NMEA text log (PASHR / XDR sentences,
    usvfast.pipeline.attitude; `reference`: a UNIX time on the log's day). Heading rates
    (times, rad/s; `usvfast.pipeline.gyro_bridge.heading_rates`) for an IMU, else None."""
    from usvfast.nav.bags import BagTopic, read_bag_imu
    from usvfast.pipeline.attitude import read_attitude_sentences

    if spec.type not in ("bag", "nmea"):
        raise NavigationError(
            f"stream {spec.id!r}: an attitude stream must be a bag topic of sensor_msgs/Imu "
            "or nmea_msgs/Sentence, or an NMEA log (type = nmea) with PASHR/XDR sentences"
        )
    try:
        if spec.type == "nmea":
            from usvfast._files import bounded_lines, regular_file

            with open(regular_file(spec.path, f"stream {spec.id!r} path"), "rb") as fh:
                lines = (b.decode("ascii", "replace") for b in bounded_lines(fh))
                t, roll, pitch, bad = read_attitude_sentences(lines, reference)
        else:
            from usvfast.pipeline.streams import check_topic

            msgtype = check_topic(
                spec.path, spec.topic, ["sensor_msgs/msg/Imu", "nmea_msgs/msg/Sentence"]
            )
            if msgtype == "sensor_msgs/msg/Imu":
                imu = read_bag_imu(spec.path, spec.topic)
                ok = _oriented(spec, imu.orientation_xyzw)
                t = imu.times[ok]
                roll, pitch = imu_roll_pitch(imu.orientation_xyzw[ok])
                rate = heading_rates(imu.angular_velocity[ok], roll, pitch)
                return t, roll, pitch, imu.skipped + int((~ok).sum()), (t, rate)
            reader = BagTopic(spec.path, spec.topic)
            t, roll, pitch, bad = read_attitude_sentences(
                ((m.time, m.data) for m in reader), reference
            )
            bad += reader.damaged
    except NavigationError:
        raise
    except ValueError as exc:
        raise NavigationError(f"attitude stream {spec.id!r}: {exc}") from exc
    if t.size == 0:
        raise NavigationError(
            f"attitude stream {spec.id!r}: no roll/pitch (PASHR or XDR PITCH/ROLL sentences)"
        )
    return t, roll, pitch, bad, None


__all__ += ["PoseGapError"]
