"""The vessel pose from navigation messages fed one at a time, for `Pipeline.process` (a ROS
callback, a socket): `LivePose` answers from the newest samples, `parse_sentence` reads one
NMEA sentence of a live stream and `sentence_utc` gives a fix's own UTC time.
"""

from __future__ import annotations

import math
from collections import deque
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from usvfast import geodesy
from usvfast.nav._fields import checksum_ok
from usvfast.pipeline.pose import NavErrors, VesselPose, _lever_ne

__all__ = ["LivePose", "parse_sentence", "sentence_utc"]


def parse_sentence(sentence: str) -> tuple[str, tuple[float, ...]] | None:
    """One NMEA sentence of a live stream -> ("fix", (lat, lon, GGA fix quality)) for
    GGA/RMC/GLL with a fix (RMC and GLL: the quality of their FAA mode, usvfast.nav.nmea),
    ("heading", (deg,)) for HDT/THS and the GNSS-compass sentences PSAT,HPR, PASHR,HPR and
    PTNL,AVR (`usvfast.nav.nmea.compass_heading`), ("attitude", (roll rad, pitch rad)) for
    PASHR and XDR PITCH/ROLL, None otherwise or when it does not parse (checksum
    checked). Its time: see `sentence_utc` (the pipeline's live path times a stream's
    sentences by the fixes' own UTC times, less the receive delay)."""
    import pynmea2

    from usvfast.nav.nmea import COMPASS_SENTENCES, MODE_QUALITY, compass_heading

    text = sentence.strip()
    if text.startswith(tuple(f"${a}," for a in COMPASS_SENTENCES)):
        body, star, given = text[1:].partition("*")
        try:
            compass = compass_heading(body) if star and checksum_ok(body, given) else None
        except (ValueError, IndexError):
            return None
        return None if compass is None else ("heading", (compass[3],))
    try:
        msg: Any = pynmea2.parse(sentence.strip(), check=True)
    except (pynmea2.ParseError, ValueError, AttributeError):
        return None
    kind = type(msg).__name__
    try:
        if kind in ("GGA", "RMC", "GLL"):
            if kind == "GGA" and int(msg.gps_qual or 0) == 0:
                return None
            if kind in ("RMC", "GLL") and getattr(msg, "status", "A") != "A":
                return None
            if kind == "GGA":
                quality = int(msg.gps_qual)
            else:
                mode = getattr(msg, "mode_indicator" if kind == "RMC" else "faa_mode", "")
                quality = MODE_QUALITY.get(mode or "A", 1)
            return "fix", (float(msg.latitude), float(msg.longitude), float(quality))
        if kind in ("HDT", "THS"):
            return "heading", (float(msg.heading),)
        if kind in ("ASHRATT", "XDR"):
            from usvfast.pipeline.attitude import attitude_from_sentence

            att = attitude_from_sentence(sentence)
            return None if att is None else ("attitude", att)
    except (TypeError, ValueError):
        return None
    return None


def sentence_utc(sentence: str, near: float, max_delay: float = 2.0) -> float | None:
    """The UNIX time (s) of a GGA/RMC/GLL sentence's own UTC time of day, taken on the UTC day
    of `near` (the message's receive time, UNIX s); None when the sentence has no time or it
    lies more than `max_delay` s from `near` (a clock that does not agree with the stamps)."""
    import pynmea2

    try:
        stamp = getattr(pynmea2.parse(sentence.strip(), check=True), "timestamp", None)
    except (pynmea2.ParseError, ValueError, AttributeError):
        return None
    if stamp is None or not hasattr(stamp, "hour"):
        return None
    of_day = stamp.hour * 3600 + stamp.minute * 60 + stamp.second + stamp.microsecond * 1e-6
    utc = math.floor(near / 86400.0) * 86400.0 + of_day
    utc += 86400.0 * round((near - utc) / 86400.0)  # across midnight
    return utc if abs(near - utc) <= max_delay else None


#: Heading-rate samples kept for the gyro bridge (20 s of a 50 Hz IMU), and how long the
#: newest rate is held when a sensor message comes before the next IMU sample (s).
_RATE_SAMPLES = 1000
_RATE_HOLD_S = 0.1


def _append(samples: deque, sample: tuple[float, ...]) -> None:
    """Keep the newest two samples; a sample at the time of the newest replaces it."""
    if samples and sample[0] <= samples[-1][0]:
        if sample[0] == samples[-1][0]:
            samples[-1] = sample
        return
    samples.append(sample)


class LivePose:
    """Pose from navigation messages fed one at a time (`add_fix`, `add_heading`,
    `add_attitude`, all with UNIX times), for `Pipeline.process`.

    `at(t)` interpolates between the two samples around t or extrapolates the last two by at
    most `max_gap` seconds; None before the first fix and heading. origin (lat, lon, h) or
    None (the first fix); lever_arm (3,) of the GNSS antenna, body FRD m; heading_offset:
    correction added to every heading, rad clockwise (an attribute: it may change); errors:
    the navigation's errors given to each pose (`NavErrors`), a fix of unknown quality taking
    the previous fix's; gyro_bridge: when the newest heading is older than three of its
    intervals (a gap), carry it forward by the heading rates given to `add_heading_rate` (the
    attitude IMU's gyro, `usvfast.pipeline.gyro_bridge.heading_rates`).
    """

    def __init__(
        self,
        origin: tuple[float, float, float] | None = None,
        lever_arm: ArrayLike = (0.0, 0.0, 0.0),
        max_gap: float = 2.0,
        heading_offset: float = 0.0,
        errors: NavErrors | None = None,
        gyro_bridge: bool = False,
    ) -> None:
        self.origin = origin
        self.gyro_bridge = bool(gyro_bridge)
        self._rates: deque[tuple[float, float]] = deque(maxlen=_RATE_SAMPLES)
        self.errors = NavErrors() if errors is None else errors
        self._fix_std = 0.0
        self.heading_offset = float(heading_offset)
        self.lever = np.asarray(lever_arm, dtype=np.float64)
        self.max_gap = float(max_gap)
        self._fix: deque[tuple[float, float, float, float]] = deque(maxlen=2)
        self._head: deque[tuple[float, float]] = deque(maxlen=2)
        self._att: deque[tuple[float, float, float]] = deque(maxlen=2)

    def add_fix(self, t: float, lat_deg: float, lon_deg: float, quality: float = -1) -> None:
        """A GNSS antenna fix (WGS84 degrees) at UNIX time t, of GGA fix `quality` (-1:
        unknown)."""
        if self.origin is None:
            self.origin = (float(lat_deg), float(lon_deg), 0.0)
        n, e, _ = geodesy.geodetic2ned(lat_deg, lon_deg, 0.0, *self.origin)
        if quality >= 0:
            self._fix_std = float(self.errors.std_of([quality])[0])
        _append(self._fix, (float(t), float(n), float(e), self._fix_std))

    def add_heading(self, t: float, heading: float) -> None:
        """A true heading (rad clockwise from north) at UNIX time t."""
        _append(self._head, (float(t), float(heading)))

    def add_attitude(self, t: float, roll: float, pitch: float) -> None:
        """Roll and pitch (rad, FRD) at UNIX time t."""
        _append(self._att, (float(t), float(roll), float(pitch)))

    def add_heading_rate(self, t: float, rate: float) -> None:
        """The heading's rate (rad/s, clockwise) at UNIX time t, from the attitude IMU."""
        if not self._rates or t > self._rates[-1][0]:
            self._rates.append((float(t), float(rate)))

    def _gyro_heading(self, t: float) -> float | None:
        """The newest heading carried to t by the heading rates (trapezoid rule), when the
        bridge is on, the heading is in a gap at t and the rates cover it (to within
        `_RATE_HOLD_S`); else None."""
        if not self.gyro_bridge or len(self._head) < 2 or not self._rates:
            return None
        (ta, _), (t0, h0) = self._head
        if t - t0 <= 3.0 * (t0 - ta) or self._rates[0][0] > t0:
            return None
        if self._rates[-1][0] < t - _RATE_HOLD_S:
            return None
        ts = np.array([r[0] for r in self._rates])
        rs = np.array([r[1] for r in self._rates])
        inside = (ts > t0) & (ts < t)
        knots = np.concatenate([[t0], ts[inside], [t]])
        rates = np.interp(knots, ts, rs)  # the newest rate held after it
        return h0 + float(np.sum(0.5 * (rates[1:] + rates[:-1]) * np.diff(knots)))

    def _spread(self, samples: deque, t: float) -> float:
        """|(t − t_a)(t − t_b)| (s²) of the two samples `_value` inter- or extrapolates from
        (0 with one sample)."""
        if len(samples) < 2:
            return 0.0
        return abs((t - samples[0][0]) * (t - samples[1][0]))

    def _value(self, samples: deque, t: float, angle: tuple[bool, ...]) -> tuple[float, ...] | None:
        if not samples:
            return None
        last = samples[-1]
        if len(samples) == 1:
            return last[1:] if abs(t - last[0]) <= self.max_gap else None
        a, b = samples[0], samples[1]
        if b[0] - a[0] <= 0 or t - b[0] > self.max_gap or t < a[0] - self.max_gap:
            return last[1:] if abs(t - last[0]) <= self.max_gap else None
        f = (t - a[0]) / (b[0] - a[0])
        out = []
        for k, is_angle in enumerate(angle):
            d = b[k + 1] - a[k + 1]
            if is_angle:
                d = (d + math.pi) % (2 * math.pi) - math.pi
            out.append(a[k + 1] + f * d)
        return tuple(out)

    def at(self, t: float) -> VesselPose | None:
        """The vessel pose at t from the newest samples, or None (no fix/heading near t)."""
        ne = self._value(self._fix, t, (False, False, False))
        h = self._value(self._head, t, (True,))
        if ne is None or h is None:
            return None
        bridged = self._gyro_heading(t)
        if bridged is not None:
            h = (bridged,)
        heading = (h[0] + self.heading_offset) % (2 * math.pi)
        dn, de = _lever_ne(self.lever, np.array(heading))
        att = self._value(self._att, t, (True, True)) or (0.0, 0.0)
        position_var = self.errors.position_var(ne[2], self._spread(self._fix, t))
        heading_var = self.errors.heading_var(self._spread(self._head, t))
        return VesselPose(
            float(t),
            ne[0] - float(dn),
            ne[1] - float(de),
            heading,
            att[0],
            att[1],
            position_var,
            heading_var,
        )
