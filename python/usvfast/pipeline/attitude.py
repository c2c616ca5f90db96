"""Roll and pitch from NMEA attitude sentences, for recordings whose attitude comes with the
GNSS/INS text stream instead of a sensor_msgs/Imu topic.

Sentences read (parsed by pynmea2, checksums checked):

- ``$PASHR`` (Hemisphere/Applanix/Trimble attitude, pynmea2's ASHRATT): UTC time of day,
  heading, roll, pitch (degrees; roll positive with the starboard side down, pitch positive
  bow up: FRD). Its own time of day is put on the day of the log's fixes (midnight rollover
  handled within half a day).
- ``$--XDR`` transducer groups of type ``A`` (angle) in degrees named ``PITCH``/``PTCH`` and
  ``ROLL`` (the same sign conventions). XDR has no time: it takes the time of the newest
  timed sentence (GGA, RMC, GLL, ZDA or PASHR) before it, or the bag message's time.

`read_attitude_sentences(lines, reference)` -> (times UNIX s, roll rad, pitch rad, damaged),
`attitude_from_sentence(sentence)` for live streams.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from typing import Any

import numpy as np

__all__ = ["attitude_from_sentence", "read_attitude_sentences"]

_DAY = 86400.0
_PITCH = {"PITCH", "PTCH"}
_ROLL = {"ROLL"}


def _parse(sentence: str) -> Any:
    import pynmea2

    try:
        return pynmea2.parse(sentence.strip(), check=True)
    except (pynmea2.ParseError, ValueError, AttributeError, TypeError):
        return None


def _tod(msg: Any) -> float | None:
    ts = getattr(msg, "timestamp", None)
    if ts is None or not hasattr(ts, "hour"):
        return None
    return ts.hour * 3600.0 + ts.minute * 60.0 + ts.second + ts.microsecond * 1e-6


def _xdr(msg: Any) -> tuple[float | None, float | None]:
    """(roll deg, pitch deg) of an XDR sentence's angle transducers (None where absent)."""
    roll = pitch = None
    data = list(msg.data)
    for k in range(0, len(data) - 3, 4):
        kind, value, unit, name = data[k : k + 4]
        if kind.upper() != "A" or unit.upper() != "D" or not value:
            continue
        try:
            v = float(value)
        except ValueError:
            continue
        if not math.isfinite(v):
            continue
        if name.upper() in _PITCH:
            pitch = v
        elif name.upper() in _ROLL:
            roll = v
    return roll, pitch


def attitude_from_sentence(sentence: str) -> tuple[float, float] | None:
    """(roll, pitch) in radians (FRD) of one PASHR or XDR sentence with both angles, else None
    (also for damaged sentences)."""
    msg = _parse(sentence)
    if msg is None:
        return None
    kind = type(msg).__name__
    if kind == "ASHRATT":
        try:
            roll, pitch = float(msg.roll), float(msg.pitch)
        except (TypeError, ValueError):
            return None
    elif kind == "XDR":
        r, p = _xdr(msg)
        if r is None or p is None:
            return None
        roll, pitch = r, p
    else:
        return None
    if not (math.isfinite(roll) and math.isfinite(pitch)):
        return None
    return math.radians(roll), math.radians(pitch)


def read_attitude_sentences(
    lines: Iterable[str | tuple[float, str]], reference: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """Attitude samples of an NMEA stream, in stream order.

    lines: sentences (text log) or (time UNIX s, sentence) pairs (bag messages: the message
    time is used for XDR and kept as a fallback for PASHR). reference: a UNIX time on the
    log's day (e.g. its first GNSS fix) placing the times of day. Returns (times, roll rad,
    pitch rad, damaged: attitude sentences that did not parse or lacked an angle), sorted by
    time; raises ValueError when `reference` is not finite.
    """
    if not math.isfinite(float(reference)):
        raise ValueError(f"reference: must be a finite UNIX time, got {reference}")
    day0 = math.floor(float(reference) / _DAY) * _DAY
    last = float(reference)
    out: list[tuple[float, float, float]] = []
    damaged = 0
    for item in lines:
        stamp, text = item if isinstance(item, tuple) else (None, item)
        if not isinstance(text, str):
            continue
        body = text.strip()
        head = body[3:6].upper() if body[:2] != "$P" else body[1:6].upper()
        is_att = head in ("PASHR", "XDR")
        msg = _parse(body)
        if msg is None:
            damaged += is_att
            continue
        tod = _tod(msg)
        if tod is not None:
            t = day0 + tod
            t += _DAY * round((last - t) / _DAY)  # within half a day of the previous time
            last = t
        elif stamp is not None:
            last = float(stamp)
        if not is_att:
            continue
        if stamp is not None and tod is None:
            t_att = float(stamp)
        else:
            t_att = last
        att = attitude_from_sentence(body)
        if att is None:
            damaged += 1
            continue
        out.append((t_att, att[0], att[1]))
    if not out:
        return np.zeros(0), np.zeros(0), np.zeros(0), damaged
    a = np.array(out, dtype=np.float64)
    order = np.argsort(a[:, 0], kind="stable")
    a = a[order]
    return a[:, 0], a[:, 1], a[:, 2], damaged
