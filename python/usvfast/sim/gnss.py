"""GNSS/heading NMEA and IMU attitude of the simulated USV.

A dual-antenna multi-band receiver like the thesis's pair of ANN-MB-00-00 antennas (section
4.1.5) on an RTK-capable receiver: GGA (position, fix quality, satellites, HDOP), RMC (speed
and course over ground, date) and HDT (true heading from the antenna baseline) every epoch.
Positions are those of the rear antenna, 0.94 m aft of the body origin (eq. 4.3), moved by
the USV's heading, roll and pitch; the heading is that of the antenna baseline.

Errors (`GnssErrors`): white position noise plus a slowly wandering (first-order Gauss–Markov)
bias per axis; a constant heading bias (antenna baseline misalignment) plus white heading
noise; outages of one to two seconds with no sentences at all, after which the fix degrades
to RTK float for a few seconds; single sentences lost at random; a receive latency between
the epoch (the time in the sentence) and the time the driver stamps the message. Sentences
are rendered by pynmea2 (checksums included).

The IMU gives the orientation of the body (ROS REP-103: body FLU in a local ENU frame, as a
quaternion x, y, z, w) at 50 Hz: the wave roll and pitch with a little noise, and a yaw with a
magnetic offset (use the GNSS heading, not the IMU yaw).
"""

from __future__ import annotations

import datetime as _dt
import math
from dataclasses import dataclass

import numpy as np
import pynmea2
from scipy.spatial.transform import Rotation

from usvfast import geodesy
from usvfast._validate import instance
from usvfast.sim.scene import World

KNOT = 1852.0 / 3600.0  # m/s
#: GNSS antenna (the rear one, whose position the receiver reports) in the body frame (FRD),
#: m: 0.94 m aft of the body origin (thesis eq. 4.3).
GNSS_LEVER_ARM = (-0.94, 0.0, 0.0)
GEOID_SEPARATION = 39.9  # m, ellipsoid above mean sea level at Trondheim (approx.)
_NED_TO_ENU = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
_FLU_TO_FRD = np.diag([1.0, -1.0, -1.0])


@dataclass(frozen=True)
class GnssErrors:
    """Error model of the receiver.

    rate : epochs per second (5–20). position_sigma : white noise per horizontal axis, m.
    bias_sigma, bias_tau : Gauss–Markov bias per axis (standard deviation m, correlation s).
    heading_bias_deg : constant heading error, degrees (None: drawn from the seed, 0.3–1.0°
    with a random sign). heading_sigma_deg : white heading noise, degrees. latency : (min,
    max) receive delay, s. outages_per_minute : mean number of 1–2 s outages. loss : chance
    that a single sentence is lost. float_seconds : time in RTK float after an outage, s;
    float_sigma : extra white noise then, m.
    """

    rate: float = 10.0
    position_sigma: float = 0.02
    bias_sigma: float = 0.03
    bias_tau: float = 60.0
    heading_bias_deg: float | None = None
    heading_sigma_deg: float = 0.15
    latency: tuple[float, float] = (0.04, 0.08)
    outages_per_minute: float = 1.0
    loss: float = 0.01
    float_seconds: float = 3.0
    float_sigma: float = 0.10

    def __post_init__(self) -> None:
        if not 5.0 <= self.rate <= 20.0:
            raise ValueError(f"rate: expected 5..20 Hz, got {self.rate}")
        for name in ("position_sigma", "bias_sigma", "heading_sigma_deg", "float_sigma"):
            if not getattr(self, name) >= 0:
                raise ValueError(f"{name}: expected >= 0, got {getattr(self, name)}")
        if not 0.0 <= self.loss < 1.0:
            raise ValueError(f"loss: expected 0 <= loss < 1, got {self.loss}")

    @property
    def horizontal_sigma(self) -> float:
        """Standard deviation of the horizontal error per axis with an RTK fixed fix, m."""
        return float(np.hypot(self.position_sigma, self.bias_sigma))


@dataclass
class GnssRecord:
    """One sentence: `stamp` (UNIX s, when the driver received it), `epoch` (UNIX s, the fix
    time written in it), `sentence` (text with checksum, no line end), `kind` ('GGA', 'RMC',
    'HDT')."""

    stamp: float
    epoch: float
    sentence: str
    kind: str


@dataclass
class GnssTruth:
    """Per epoch: `epoch` (k,) UNIX s, true (north, east) (k, 2) m and heading (k,) rad of the
    reference point, measured (north, east) (k, 2) m and heading (k,) rad (NaN when not
    sent), `quality` (k,) GGA fix quality (0 in outages), and the heading bias rad."""

    epoch: np.ndarray
    true_ne: np.ndarray
    true_heading: np.ndarray
    measured_ne: np.ndarray
    measured_heading: np.ndarray
    quality: np.ndarray
    heading_bias: float


def _ddmm(value: float, pos: str, neg: str, width: int) -> tuple[str, str]:
    hemi = pos if value >= 0 else neg
    v = abs(value)
    d = int(v)
    minutes = (v - d) * 60.0
    if round(minutes, 7) >= 60.0:
        d, minutes = d + 1, 0.0
    return f"{d:0{width}d}{minutes:010.7f}", hemi


def _hms(t: float) -> str:
    day = _dt.datetime.fromtimestamp(round(t, 2), tz=_dt.timezone.utc)
    return day.strftime("%H%M%S.") + f"{day.microsecond // 10000:02d}"


def _sentence(talker: str, kind: str, fields: list[str]) -> str:
    return str(pynmea2.parse(f"${talker}{kind},{','.join(fields)}", check=False).render())


def simulate_gnss(
    world: World,
    start: float,
    duration: float,
    errors: GnssErrors | None = None,
    *,
    seed: int = 0,
    lever_arm: tuple[float, float, float] = GNSS_LEVER_ARM,
    waterline_height: float = 0.30,
) -> tuple[list[GnssRecord], GnssTruth]:
    """GGA + RMC + HDT sentences of the USV's antenna at `lever_arm` (body FRD, m) over
    [start, start + duration] UNIX s, in receive order, and the per-epoch truth (of the
    antenna). Deterministic given `seed`."""
    instance("world", world, World)
    if errors is not None:
        instance("errors", errors, GnssErrors)
    if not (math.isfinite(start) and math.isfinite(duration) and 0 <= duration <= 1e6):
        raise ValueError(
            f"start, duration: expected finite, 0 <= duration <= 1e6 s, got {start}, {duration}"
        )
    errors = errors or GnssErrors()
    rng = np.random.default_rng([seed, 4])
    k = np.arange(int(np.floor(duration * errors.rate + 1e-9)) + 1)
    rel = k / errors.rate
    epoch = start + rel
    n, e, heading = world.usv.pose(rel)
    roll, pitch, heave = world.waves.at(rel)
    arm = np.einsum(
        "kij,j->ki",
        Rotation.from_euler("ZYX", np.column_stack([heading, pitch, roll])).as_matrix(),
        np.asarray(lever_arm, dtype=np.float64),
    )
    n, e = n + arm[:, 0], e + arm[:, 1]
    up = waterline_height + heave - arm[:, 2]
    # Gauss–Markov bias per axis, white noise on top
    a = np.exp(-1.0 / (errors.rate * errors.bias_tau))
    bias = np.zeros((k.size, 2))
    b = rng.normal(0.0, errors.bias_sigma, 2)
    drive = rng.normal(0.0, errors.bias_sigma * np.sqrt(1 - a * a), (k.size, 2))
    for i in range(k.size):
        b = a * b + drive[i] if i else b
        bias[i] = b
    noise = rng.normal(0.0, errors.position_sigma, (k.size, 2))
    # outages and the RTK-float time after them
    quality = np.full(k.size, 4)
    n_out = rng.poisson(errors.outages_per_minute * duration / 60.0)
    for _ in range(n_out):
        lo = min(5.0, 0.2 * duration)
        t_out = rng.uniform(lo, max(duration - 2.0, lo))
        length = rng.uniform(1.0, 2.0)
        quality[(rel >= t_out) & (rel < t_out + length)] = 0
        after = (rel >= t_out + length) & (rel < t_out + length + errors.float_seconds)
        quality[after & (quality != 0)] = 5
    noise[quality == 5] += rng.normal(0.0, errors.float_sigma, (int((quality == 5).sum()), 2))
    measured = np.column_stack([n, e]) + bias + noise
    if errors.heading_bias_deg is None:
        hb = np.radians(rng.uniform(0.3, 1.0) * rng.choice([-1.0, 1.0]))
    else:
        hb = np.radians(errors.heading_bias_deg)
    heading_m = np.mod(
        heading + hb + rng.normal(0.0, np.radians(errors.heading_sigma_deg), k.size), 2 * np.pi
    )
    # speed and course over ground of the reference point (central differences) plus noise
    dt = 0.05
    n1, e1, _ = world.usv.pose(rel + dt)
    n0, e0, _ = world.usv.pose(np.maximum(rel - dt, 0.0))
    span = np.where(rel - dt >= 0, 2 * dt, dt + rel)
    vn, ve = (n1 - n0) / span, (e1 - e0) / span
    sog = np.hypot(vn, ve) + rng.normal(0.0, 0.03, k.size)
    cog = np.degrees(np.mod(np.arctan2(ve, vn), 2 * np.pi))
    lat0, lon0, h0 = world.origin
    lat, lon, h = geodesy.ned2geodetic(measured[:, 0], measured[:, 1], -up, lat0, lon0, h0)
    latency = rng.uniform(*errors.latency, size=k.size)  # one per epoch: sentences stay in order
    lost = rng.random((k.size, 3)) < errors.loss
    sats = np.clip(np.round(22 + 2 * np.sin(rel / 40.0) + rng.normal(0, 0.5, k.size)), 12, 30)
    records: list[GnssRecord] = []
    sent_heading = np.full(k.size, np.nan)
    for i in range(k.size):
        if quality[i] == 0:
            continue  # outage: the receiver sends nothing
        hms = _hms(epoch[i])
        la, ns = _ddmm(float(lat[i]), "N", "S", 2)
        lo, ew = _ddmm(float(lon[i]), "E", "W", 3)
        hdop = 0.5 + 0.1 * np.sin(rel[i] / 17.0)
        alt = float(h[i]) - GEOID_SEPARATION
        age = "1.0"
        gga = [hms, la, ns, lo, ew, str(quality[i]), f"{int(sats[i]):02d}", f"{hdop:.2f}"]
        gga += [f"{alt:.3f}", "M", f"{GEOID_SEPARATION:.1f}", "M", age, "0000"]
        day = _dt.datetime.fromtimestamp(round(epoch[i], 2), tz=_dt.timezone.utc)
        mode = "R" if quality[i] == 4 else "F"
        rmc = [hms, "A", la, ns, lo, ew, f"{max(sog[i], 0.0) / KNOT:.3f}", f"{cog[i]:.2f}"]
        rmc += [day.strftime("%d%m%y"), "", "", mode, "V"]
        hdt = [f"{np.degrees(heading_m[i]):.3f}", "T"]
        for j, (kind, fields) in enumerate((("GGA", gga), ("RMC", rmc), ("HDT", hdt))):
            if lost[i, j]:
                continue
            stamp = float(epoch[i] + latency[i] + 0.002 * j)
            records.append(GnssRecord(stamp, float(epoch[i]), _sentence("GN", kind, fields), kind))
            if kind == "HDT":
                sent_heading[i] = heading_m[i]
    records.sort(key=lambda r: r.stamp)
    measured_ne = np.where((quality > 0)[:, None], measured, np.nan)
    truth = GnssTruth(
        epoch, np.column_stack([n, e]), heading, measured_ne, sent_heading, quality, float(hb)
    )
    return records, truth


@dataclass
class ImuSamples:
    """IMU messages: `time` (k,) UNIX s, `orientation_xyzw` (k, 4) body FLU in local ENU,
    `angular_velocity` (k, 3) rad/s and `linear_acceleration` (k, 3) m/s² in body FLU."""

    time: np.ndarray
    orientation_xyzw: np.ndarray
    angular_velocity: np.ndarray
    linear_acceleration: np.ndarray


def simulate_imu(
    world: World,
    start: float,
    duration: float,
    *,
    rate: float = 50.0,
    attitude_sigma_deg: float = 0.05,
    yaw_offset_deg: float = 2.0,
    seed: int = 0,
) -> ImuSamples:
    """IMU samples over [start, start + duration] at `rate` Hz (orientation of the wave
    roll/pitch and the heading + `yaw_offset_deg`, noise `attitude_sigma_deg`)."""
    instance("world", world, World)
    if not (math.isfinite(start) and math.isfinite(duration) and 0 <= duration <= 1e6):
        raise ValueError(
            f"start, duration: expected finite, 0 <= duration <= 1e6 s, got {start}, {duration}"
        )
    if not (math.isfinite(rate) and 0 < rate <= 1e4):
        raise ValueError(f"rate: expected 0 < rate <= 1e4 Hz, got {rate}")
    if not rate > 0:
        raise ValueError(f"rate: expected > 0 Hz, got {rate}")
    rng = np.random.default_rng([seed, 5])
    rel = np.arange(int(np.floor(duration * rate + 1e-9)) + 1) / rate
    _, _, heading = world.usv.pose(rel)
    roll, pitch, _ = world.waves.at(rel)
    sig = np.radians(attitude_sigma_deg)
    r = roll + rng.normal(0, sig, rel.size)
    p = pitch + rng.normal(0, sig, rel.size)
    y = heading + np.radians(yaw_offset_deg) + rng.normal(0, sig, rel.size)
    # NED <- FRD (ZYX yaw, pitch, roll) -> ENU <- FLU
    r_nb = Rotation.from_euler("ZYX", np.column_stack([y, p, r])).as_matrix()
    r_enu_flu = _NED_TO_ENU @ r_nb @ _FLU_TO_FRD
    quat = Rotation.from_matrix(r_enu_flu).as_quat()  # x, y, z, w
    quat *= np.where(quat[:, 3:4] < 0, -1.0, 1.0)
    roll_rate, pitch_rate = world.waves.rates(rel)
    _, _, h2 = world.usv.pose(rel + 0.01)
    yaw_rate = np.angle(np.exp(1j * (h2 - heading))) / 0.01
    # FRD rates (p, q, r) -> FLU (p, -q, -r); small-angle body rates
    gyro = np.column_stack([roll_rate, -pitch_rate, -yaw_rate]) + rng.normal(
        0, 0.002, (rel.size, 3)
    )
    g_flu = np.einsum("kji,j->ki", r_enu_flu, np.array([0.0, 0.0, 9.81]))
    accel = g_flu + rng.normal(0, 0.02, (rel.size, 3))
    return ImuSamples(start + rel, quat, gyro, accel)
