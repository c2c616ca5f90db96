"""AIS feeds made the way a class A transponder sends them, for fusion tests.

Positions come from a truth trajectory (Joyride's target GNSS, or a simulated vessel),
encoded by pyais as real AIVDM sentences: types 1 and 3 (position reports; 3 every fifth) at
the ITU-R M.1371-5 Table 1 reporting intervals for the vessel's speed and course changes,
type 5 (static and voyage data, name) every 6 minutes. pyais quantises exactly as AIS does:
latitude/longitude in 1/10,000 min, speed 0.1 kn, course 0.1°, heading 1°. The position is
the GNSS fix of a whole UTC second (the message's `second` field); it goes out 0-1 s later in
its slot and the log stamps the reception with an NMEA 4.10 tag block `\\c:<UNIX s>*hh\\`
(whole seconds, as in real feeds). Reports are lost at random (`loss`) and in outages
(`outages`, VHF shadowing), and a transponder GNSS error (first-order Gauss-Markov, `gnss_std`
metres, 60 s correlation) is added to the position.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import reduce
from operator import xor
from pathlib import Path

import numpy as np
from pyais import encode_dict
from scipy.interpolate import CubicHermiteSpline

from usvfast import geodesy

KNOT = 1852.0 / 3600.0
#: Assumed origin of the Joyride tangent plane (Trondheim harbour; the recording has none).
JOYRIDE_ORIGIN = (63.4389, 10.3990)


def itu_interval(speed_kn: float, rot_deg_min: float) -> float:
    """ITU-R M.1371-5 Table 1, class A, under way: seconds between position reports.
    "Changing course" is taken as |rate of turn| > 5°/min."""
    turning = abs(rot_deg_min) > 5.0
    if speed_kn <= 3.0:
        return 10.0 if not turning else 10.0 / 3.0
    if speed_kn <= 14.0:
        return 10.0 / 3.0 if turning else 10.0
    if speed_kn <= 23.0:
        return 2.0 if turning else 6.0
    return 2.0


@dataclass
class Vessel:
    """A truth trajectory: times (s,) UNIX s and states (s, 4) [n, v_n, e, v_e] in the NED
    plane of `origin`; mmsi, name."""

    mmsi: int
    name: str
    times: np.ndarray
    states: np.ndarray

    def at(self, t: np.ndarray) -> np.ndarray:
        """States (k, 4) at times t by cubic Hermite interpolation of the positions."""
        n = CubicHermiteSpline(self.times, self.states[:, 0], self.states[:, 1])
        e = CubicHermiteSpline(self.times, self.states[:, 2], self.states[:, 3])
        return np.stack([n(t), n(t, 1), e(t), e(t, 1)], axis=1)


def _tag(t: int) -> str:
    body = f"c:{t}"
    return f"\\{body}*{reduce(xor, body.encode(), 0):02X}\\"


def transmissions(
    vessel: Vessel, rng: np.random.Generator, *, t_end: float | None = None
) -> list[float]:
    """Fix times (whole UTC seconds) of the position reports over the vessel's time span."""
    t, stop = float(np.ceil(vessel.times[0])), float(t_end or vessel.times[-1])
    out = []
    t += float(rng.integers(0, 3))
    while t <= stop:
        out.append(t)
        s0, s1 = vessel.at(np.array([t, t + 1.0]))
        speed = math.hypot(s0[1], s0[3]) / KNOT
        c0, c1 = math.atan2(s0[3], s0[1]), math.atan2(s1[3], s1[1])
        rot = math.degrees(math.atan2(math.sin(c1 - c0), math.cos(c1 - c0))) * 60.0
        t += max(1.0, round(itu_interval(speed, rot)))
    return out


def ais_lines(
    vessel: Vessel,
    origin: tuple[float, float],
    rng: np.random.Generator,
    *,
    loss: float = 0.15,
    outages: tuple[tuple[float, float], ...] = (),
    gnss_std: float = 3.0,
    position: bool = True,
) -> list[tuple[float, str]]:
    """(receive time, tag-blocked AIVDM line) of one vessel's reports (types 1/3 and 5).
    outages: (start, end) UNIX s intervals with no reception. position=False sends reports
    with latitude/longitude "not available" (91°/181°)."""
    fixes = np.array(transmissions(vessel, rng))
    states = vessel.at(fixes)
    # Transponder GNSS error: Gauss-Markov with 60 s correlation.
    err = np.zeros((len(fixes), 2))
    for k in range(1, len(fixes)):
        a = math.exp(-(fixes[k] - fixes[k - 1]) / 60.0)
        err[k] = a * err[k - 1] + math.sqrt(1 - a * a) * gnss_std * rng.standard_normal(2)
    if len(fixes):
        err[0] = gnss_std * rng.standard_normal(2)
    lat, lon, _ = geodesy.ned2geodetic(
        states[:, 0] + err[:, 0], states[:, 2] + err[:, 1], 0.0, origin[0], origin[1], 0.0
    )
    out: list[tuple[float, str]] = []
    last_static = -math.inf
    for k, t_fix in enumerate(fixes.tolist()):
        t_rx = t_fix + float(rng.uniform(0.0, 1.0))
        lost = rng.random() < loss or any(a <= t_rx <= b for a, b in outages)
        if t_rx - last_static >= 360.0:
            last_static = t_rx
            if not lost:
                static = encode_dict(
                    {
                        "type": 5,
                        "msg_type": 5,
                        "mmsi": vessel.mmsi,
                        "shipname": vessel.name,
                        "callsign": "LH" + str(vessel.mmsi)[-4:],
                        "ship_type": 37,
                        "to_bow": 6,
                        "to_stern": 2,
                        "to_port": 1,
                        "to_starboard": 1,
                    },
                    talker_id="AI",
                    sentence_type="VDM",
                    seq_id=k % 10,
                )
                for part in static:
                    out.append((t_rx, _tag(int(t_rx)) + part))
        if lost:
            continue
        s = states[k]
        speed = math.hypot(s[1], s[3]) / KNOT
        course = math.degrees(math.atan2(s[3], s[1])) % 360.0
        kind = 3 if k % 5 == 4 else 1
        msg = {
            "type": kind,
            "msg_type": kind,  # pyais takes the payload's type field from here
            "mmsi": vessel.mmsi,
            "status": 0,
            "turn": 0,
            "speed": round(speed, 1),
            "accuracy": 0,
            "lon": float(lon[k]) if position else 181.0,
            "lat": float(lat[k]) if position else 91.0,
            "course": round(course, 1) % 360.0,
            "heading": round(course) % 360,
            "second": int(t_fix) % 60,
        }
        for part in encode_dict(msg, talker_id="AI", sentence_type="VDM"):
            out.append((t_rx, _tag(int(t_rx)) + part))
    return out


def feed(*lists: list[tuple[float, str]]) -> list[str]:
    """Merge vessels' lines into one log in receive order."""
    allv = sorted((x for lst in lists for x in lst), key=lambda x: x[0])
    return [line for _, line in allv]


def straight(mmsi: int, name: str, t0: float, t1: float, p0, v) -> Vessel:
    """A vessel on a straight line from p0 (n, e) at t0 with velocity v (v_n, v_e)."""
    ts = np.arange(t0, t1 + 1.0, 1.0)
    st = np.stack(
        [
            p0[0] + v[0] * (ts - t0),
            np.full_like(ts, v[0]),
            p0[1] + v[1] * (ts - t0),
            np.full_like(ts, v[1]),
        ],
        axis=1,
    )
    return Vessel(mmsi, name, ts, st)


def joyride_scene(rec, seed: int = 1) -> tuple[list[str], dict[str, Vessel]]:
    """The Joyride target's AIS (MMSI 257000001, random 15 % losses plus two VHF outages of
    45 s and 60 s) and two decoys: DECOY (257000002) crossing the target's path at 4 m/s,
    passing through where the target is 300 s into the recording, and FARAWAY (257000003)
    ~3.6 km off. Returns (log lines in receive order, vessels by name)."""
    rng = np.random.default_rng(seed)
    t0 = float(rec.times[0])
    target = Vessel(257000001, "JOYRIDE", rec.times, rec.target)
    mid = target.at(np.array([t0 + 300.0]))[0]
    decoy = straight(257000002, "DECOY", t0, t0 + 640, (mid[0] - 1200.0, mid[2]), (4.0, 0.0))
    far = straight(257000003, "FARAWAY", t0, t0 + 640, (mid[0] + 3000, mid[2] - 2000), (0, -5.0))
    outages = ((t0 + 200.0, t0 + 245.0), (t0 + 420.0, t0 + 480.0))
    lines = feed(
        ais_lines(target, JOYRIDE_ORIGIN, rng, outages=outages),
        ais_lines(decoy, JOYRIDE_ORIGIN, rng),
        ais_lines(far, JOYRIDE_ORIGIN, rng),
    )
    return lines, {"target": target, "decoy": decoy, "far": far}


if __name__ == "__main__":
    import sys

    from usvfast.datasets import load_joyride

    # python tests/aisgen.py JOYRIDE.mat OUT.nmea: the Joyride AIS feed for `usvfast vts`.
    lines, _ = joyride_scene(load_joyride(sys.argv[1]))
    Path(sys.argv[2]).write_text("\n".join(lines) + "\n")
