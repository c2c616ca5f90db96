"""VLP-16 returns of the simulated harbour, written as the sensor's own UDP data packets.

A VLP-16 fires its 16 lasers every 55.296 µs (2.304 µs apart) while it spins; two firing
sequences make a *block* (one azimuth reading), twelve blocks a 1206-byte *data packet*:

    12 × [0xFFEE flag (u16 LE) | azimuth, 0.01° (u16)
          | 32 × (distance, 2 mm (u16), reflectivity (u8))]
    timestamp, µs past the UTC hour, of the packet's first firing (u32) | return mode 0x37
    (strongest) | product id 0x22 (VLP-16)

(VLP-16 user manual, "Data Packet Format"). Decoders give the second firing of a block,
and each laser within a firing, an azimuth interpolated from the block's azimuth at the
packet's mean azimuth step, rounded to 0.01° (`decoded_azimuths`); the rays here are cast
along exactly those azimuths, from each laser's vertical offset, so decoding a packet gives
back the simulated points up to the 2 mm distance step. A *scan*
(`velodyne_msgs/VelodyneScan`) holds the packets of one rotation, cut where the azimuth wraps
through 0° (straight ahead), stamped with its last packet's time as the ROS velodyne driver
does.

The ray casting is `usvfast.lidar.simulator.VLP16Simulator.cast` (walls, boxes, cylinders),
with every ray starting from the sensor's true position and attitude at its firing time
(USV path, heading, wave roll/pitch/heave); the water absorbs the beams except for rare
returns from wave crests.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from usvfast._validate import as_float_array, integer
from usvfast.frames import rotation_matrix
from usvfast.lidar.frame import POINT_DTYPE
from usvfast.lidar.simulator import Scene, VLP16Simulator, Wall
from usvfast.sim.scene import World

#: Laser elevations by laser id (firing order), degrees (VLP-16 manual).
VLP16_ELEVATION_DEG = np.array([-15, 1, -13, 3, -11, 5, -9, 7, -7, 9, -5, 11, -3, 13, -1, 15.0])
#: Vertical offset of each laser's origin, m (z = d·sin(elevation) + offset), as decoders
#: apply it for the VLP-16: −41.91 mm · tan(elevation) (11.2 mm at −15°).
VLP16_VERTICAL_OFFSET = -0.04191 * np.tan(np.radians(VLP16_ELEVATION_DEG))
FIRING_PERIOD = 55.296e-6  # s between firing sequences
LASER_PERIOD = 2.304e-6  # s between lasers of one sequence
BLOCK_PERIOD = 2 * FIRING_PERIOD
DISTANCE_STEP = 0.002  # m per distance count
PACKET_SIZE = 1206
STRONGEST_RETURN, VLP16_PRODUCT_ID = 0x37, 0x22
#: LiDAR mount of the thesis (eq. 4.1): 0.28 m aft of and 0.57 m above the body origin.
LIDAR_LEVER_ARM = (-0.28, 0.0, -0.57)

_CHANNEL = np.dtype([("distance", "<u2"), ("reflectivity", "u1")])
_BLOCK = np.dtype([("flag", "<u2"), ("azimuth", "<u2"), ("channels", _CHANNEL, (32,))])
PACKET_DTYPE = np.dtype(
    [("blocks", _BLOCK, (12,)), ("timestamp", "<u4"), ("return_mode", "u1"), ("product", "u1")]
)
_FLU_TO_FRD = np.diag([1.0, -1.0, -1.0])


@dataclass
class Scan:
    """One rotation: `packets` (p, 1206) uint8, `packet_times` (p,) UNIX s (first firing of
    each packet), `stamp` (UNIX s, the last packet's time), and the simulated returns as the
    decoder will report them: `points` (n,) `POINT_DTYPE` (sensor frame, times relative to
    `stamp`), `object_ids` (n,) str ('' for walls and buildings, 'water' for wave crests),
    `kinds` (n,) str."""

    packets: np.ndarray
    packet_times: np.ndarray
    stamp: float
    points: np.ndarray
    object_ids: np.ndarray
    kinds: np.ndarray


def decoded_azimuths(block_azimuths: np.ndarray) -> np.ndarray:
    """Azimuth (0.01° counts, int) a decoder gives each (packet, block, firing, laser):
    (p, 12) block azimuths -> (p, 12, 2, 16).

    velodyne-decoder interpolates with one azimuth step per block for the whole packet,
    (last block − first block) / 11, in single precision: block azimuth + step · (laser ·
    2.304 + firing · 55.296) / 110.592 µs, rounded to the nearest count. The same float32
    arithmetic here gives the same counts.
    """
    b = np.asarray(block_azimuths)
    if b.dtype.kind not in "iu" or b.ndim != 2 or b.shape[1] != 12:
        raise ValueError(
            f"block_azimuths: expected (p, 12) integer counts, got {b.dtype} {b.shape}"
        )
    az = np.asarray(block_azimuths, dtype=np.int64)
    f32 = np.float32
    step = np.mod(az[:, -1] - az[:, 0], 36000).astype(f32) / f32(11.0)
    t = np.arange(16, dtype=f32)[None, :] * f32(2.304) + np.arange(2, dtype=f32)[:, None] * f32(
        55.296
    )
    out = az.astype(f32)[:, :, None, None] + (step[:, None, None, None] * t[None, None]) / f32(
        110.592
    )
    return np.mod(np.floor(out.astype(np.float64) + 0.5).astype(np.int64), 36000)


class Vlp16Recorder:
    """Simulates a VLP-16 on the USV of a `World`, one scan at a time.

    rpm : rotation speed (600 = 10 Hz). lever_arm, ypr_deg : mount body (FRD) <- sensor (FLU;
    yaw, pitch, roll degrees). waterline_height : body origin above the water, m.
    range_noise : standard deviation of the range error, m. max_range : m. crest_probability
    : chance that a beam meeting the water 2–15 m away returns from a wave crest.
    seed : noise seed. start : UNIX s of the first firing; azimuth0_deg : azimuth then.
    buildings : whether the buildings behind the quays return points (False keeps recordings
    small: they are most of a harbour scan's returns but never reach the water-level slice).
    """

    def __init__(
        self,
        world: World,
        *,
        start: float,
        rpm: float = 600.0,
        lever_arm: tuple[float, float, float] = LIDAR_LEVER_ARM,
        ypr_deg: tuple[float, float, float] = (0.0, 0.0, 0.0),
        waterline_height: float = 0.30,
        range_noise: float = 0.02,
        max_range: float = 100.0,
        crest_probability: float = 0.002,
        seed: int = 0,
        azimuth0_deg: float = 180.0,
        buildings: bool = True,
    ) -> None:
        if not 300.0 <= rpm <= 1200.0:
            raise ValueError(f"rpm: expected 300..1200 (VLP-16), got {rpm}")
        self.world = world
        self.start = float(start)
        self.rate = rpm * 6.0  # deg/s
        self.lever_arm = np.asarray(lever_arm, dtype=np.float64)
        y, p, r = np.radians(ypr_deg)
        self.r_body_sensor = rotation_matrix(r, p, y) @ _FLU_TO_FRD
        self.waterline_height = float(waterline_height)
        self.range_noise = float(range_noise)
        self.max_range = float(max_range)
        self.crest_probability = float(crest_probability)
        self.rng = np.random.default_rng([seed, 3])
        self.azimuth0 = float(azimuth0_deg)
        self.buildings = bool(buildings)
        self._caster = VLP16Simulator(Scene([]))
        self._laser_bias = np.random.default_rng([seed, 6]).integers(-3, 4, 16).astype(float)
        self._next_packet = 0
        el = np.radians(VLP16_ELEVATION_DEG)
        self._cos_el, self._sin_el = np.cos(el), np.sin(el)

    # --- timing ---------------------------------------------------------------------
    def _block_azimuths(self, packets: np.ndarray) -> np.ndarray:
        firing = packets[:, None] * 24 + 2 * np.arange(12)[None, :]
        deg = self.azimuth0 + self.rate * firing * FIRING_PERIOD
        return np.mod(np.floor(np.mod(deg, 360.0) * 100 + 0.5).astype(np.int64), 36000)

    def next_scan(self) -> Scan:
        """The next rotation's packets (cut where the first block's azimuth wraps)."""
        per_rev = int(np.ceil(360.0 / (self.rate * 12 * BLOCK_PERIOD))) + 2
        cand = self._next_packet + np.arange(per_rev)
        first = self._block_azimuths(cand)[:, 0]
        # the first scan starts wherever the sensor is; every later one right after a wrap
        wraps = np.flatnonzero(np.diff(first) < 0)
        packets = cand[: int(wraps[0]) + 1]
        self._next_packet = int(packets[-1]) + 1
        return self._scan(packets)

    def _cast(self, bodies, o_w, height, un, ue, tan) -> tuple[np.ndarray, np.ndarray]:
        """`VLP16Simulator.cast` over the bodies, each against the rays whose bearing can
        reach it (bodies beyond the maximum range are skipped)."""
        best = np.full(un.size, np.inf)
        label = np.full(un.size, -1, dtype=np.int64)
        centre = o_w[:, :2].mean(axis=0)
        bearing = np.arctan2(ue, un)
        for k, b in enumerate(bodies):
            if b.kind == "building" and not self.buildings:
                continue
            c, radius = _extent(b.shape)
            dist = float(np.hypot(*(c - centre)))
            if dist - radius > self.max_range:
                continue
            reach = radius + 0.5  # the sensor moves a few decimetres during a scan
            if dist > reach:
                half = np.arcsin(reach / dist)
                to = np.arctan2(c[1] - centre[1], c[0] - centre[0])
                off = np.mod(bearing - to + np.pi, 2 * np.pi) - np.pi
                idx = np.flatnonzero(np.abs(off) <= half)
                if idx.size == 0:
                    continue
            else:
                idx = np.arange(un.size)
            r, _ = self._caster.cast(
                [b.shape], (o_w[idx, 0], o_w[idx, 1]), height[idx], un[idx], ue[idx], tan[idx]
            )
            closer = r < best[idx]
            best[idx[closer]] = r[closer]
            label[idx[closer]] = k
        return best, label

    # --- one scan ---------------------------------------------------------------------
    def _scan(self, packets: np.ndarray) -> Scan:
        p = packets.size
        block_az = self._block_azimuths(packets)
        az = decoded_azimuths(block_az)  # (p, 12, 2, 16)
        packet_t = self.start + packets * 24 * FIRING_PERIOD
        seq_t = packet_t[:, None, None] + (
            np.arange(12)[:, None] * BLOCK_PERIOD + np.arange(2)[None, :] * FIRING_PERIOD
        )  # (p, 12, 2)
        ray_t = seq_t[..., None] + np.arange(16) * LASER_PERIOD  # (p, 12, 2, 16)
        stamp = float(packet_t[-1])
        # pose per firing sequence (the sensor moves < 1 mm within a sequence)
        rel = seq_t.ravel() - self.start
        world = self.world
        n, e, heading = world.usv.pose(rel)
        roll, pitch, heave = world.waves.at(rel)
        r_nb = _rotations(roll, pitch, heading)  # (s, 3, 3)
        r_ns = r_nb @ self.r_body_sensor
        body = np.column_stack([n, e, -(self.waterline_height + heave)])
        origin0 = body + r_nb @ self.lever_arm  # (s, 3)
        a = np.radians(az.reshape(-1, 16) / 100.0)  # (s, 16)
        ce, se = self._cos_el[None, :], self._sin_el[None, :]
        d_s = np.stack([ce * np.cos(a), -ce * np.sin(a), np.broadcast_to(se, a.shape)], -1)
        d_w = np.einsum("sij,slj->sli", r_ns, d_s)  # (s, 16, 3) NED
        off = np.zeros((16, 3))
        off[:, 2] = VLP16_VERTICAL_OFFSET
        o_w = origin0[:, None, :] + np.einsum("sij,lj->sli", r_ns, off)
        d_w, o_w = d_w.reshape(-1, 3), o_w.reshape(-1, 3)
        horiz = np.hypot(d_w[:, 0], d_w[:, 1])
        un, ue = d_w[:, 0] / horiz, d_w[:, 1] / horiz
        tan = -d_w[:, 2] / horiz
        height = -o_w[:, 2]
        bodies = world.bodies_at(float(np.mean(rel)))
        best, label = self._cast(bodies, o_w, height, un, ue, tan)
        with np.errstate(divide="ignore"):
            r_water = np.where(tan < 0, height / np.where(tan < 0, -tan, 1.0), np.inf)
        hit = np.isfinite(best) & (best < r_water)
        crest = (
            ~hit
            & (r_water >= 2.0)
            & (r_water <= 15.0)
            & (self.rng.random(best.size) < self.crest_probability)
        )
        r = np.where(hit, best, np.where(crest, r_water, np.nan))
        slant = r / horiz + self.rng.normal(0.0, self.range_noise, r.size)
        ok = (hit | crest) & (slant > 0.5) & (slant < min(self.max_range, 65535 * DISTANCE_STEP))
        counts = np.where(ok, np.floor(np.nan_to_num(slant) / DISTANCE_STEP + 0.5), 0).astype(
            np.uint16
        )
        refl_body = np.array([b.reflectivity for b in bodies] + [0.0])
        # calibrated reflectivity: the surface's, fading a little with range, and a fixed
        # per-laser bias (lasers differ by a few counts)
        laser_bias = np.tile(self._laser_bias, r.size // 16)
        fade = 1.0 - 0.25 * np.clip(np.nan_to_num(slant) / 100.0, 0.0, 1.0)
        refl = np.where(crest, 4.0, refl_body[label]) * fade + laser_bias
        refl = np.where(ok, np.clip(np.floor(refl + 0.5), 1, 255), 0).astype(np.uint8)
        raw = np.zeros(p, dtype=PACKET_DTYPE)
        raw["blocks"]["flag"] = 0xEEFF
        raw["blocks"]["azimuth"] = block_az
        raw["blocks"]["channels"]["distance"] = counts.reshape(p, 12, 32)
        raw["blocks"]["channels"]["reflectivity"] = refl.reshape(p, 12, 32)
        raw["timestamp"] = _micros_past_hour(packet_t)
        raw["return_mode"] = STRONGEST_RETURN
        raw["product"] = VLP16_PRODUCT_ID
        # the points as a decoder reports them
        idx = np.flatnonzero(ok)
        dist = counts[idx].astype(np.float64) * DISTANCE_STEP
        laser = idx % 16
        ang = np.radians(az.reshape(-1)[idx] / 100.0)
        xy = dist * self._cos_el[laser]
        pts = np.empty(idx.size, dtype=POINT_DTYPE)
        pts["x"] = xy * np.cos(ang)
        pts["y"] = -xy * np.sin(ang)
        pts["z"] = dist * self._sin_el[laser] + VLP16_VERTICAL_OFFSET[laser]
        pts["intensity"] = refl[idx]
        pts["ring"] = np.argsort(np.argsort(VLP16_ELEVATION_DEG))[laser]
        pts["time"] = ray_t.reshape(-1)[idx] - stamp
        ids = np.array([b.object_id for b in bodies] + [""], dtype=object)
        kinds = np.array([b.kind for b in bodies] + ["water"], dtype=object)
        lab = np.where(crest[idx], len(bodies), label[idx])
        obj = ids[lab]
        obj[crest[idx]] = "water"
        return Scan(
            raw.view(np.uint8).reshape(p, PACKET_SIZE), packet_t, stamp, pts, obj, kinds[lab]
        )


def _extent(shape) -> tuple[np.ndarray, float]:
    """Centre (2,) and radius (m) of a circle around a Wall or Box footprint."""
    if isinstance(shape, Wall):
        poly = np.asarray(shape.polyline, dtype=np.float64)
        lo, hi = poly.min(axis=0), poly.max(axis=0)
        return (lo + hi) / 2, float(np.hypot(*(hi - lo)) / 2)
    return np.asarray(shape.center, dtype=np.float64), float(
        np.hypot(shape.length, shape.width) / 2
    )


def _rotations(roll: np.ndarray, pitch: np.ndarray, yaw: np.ndarray) -> np.ndarray:
    """(s, 3, 3) stack of `rotation_matrix(roll, pitch, yaw)` (NED <- body, ZYX)."""
    sf, cf = np.sin(roll), np.cos(roll)
    st, ct = np.sin(pitch), np.cos(pitch)
    sp, cp = np.sin(yaw), np.cos(yaw)
    return np.stack(
        [
            np.stack([ct * cp, sf * st * cp - cf * sp, cf * st * cp + sf * sp], -1),
            np.stack([ct * sp, sf * st * sp + cf * cp, cf * st * sp - sf * cp], -1),
            np.stack([-st, sf * ct, cf * ct], -1),
        ],
        -2,
    )


def _micros_past_hour(t: np.ndarray) -> np.ndarray:
    """UNIX s -> µs past the UTC hour (uint32), the VLP-16's GPS-synchronised timestamp."""
    us = np.floor((np.asarray(t) % 3600.0) * 1e6 + 0.5).astype(np.int64)
    return np.mod(us, 3_600_000_000).astype(np.uint32)


def udp_frame(payload: bytes, port: int, ip_id: int) -> bytes:
    """One Ethernet / IPv4 / UDP broadcast frame as a laptop captures a Velodyne's packets:
    from the sensor (192.168.1.201) to `port`, IPv4 identification `ip_id` (taken mod 2^16).
    Needs dpkt (the `sim` extra). Raises TypeError / ValueError naming a bad argument."""
    import dpkt

    if not isinstance(payload, bytes | bytearray):
        raise TypeError(f"payload: expected bytes, got {type(payload).__name__}")
    port = integer("port", port, low=0, high=65535)
    ip_id = integer("ip_id", ip_id)
    udp = dpkt.udp.UDP(sport=port, dport=port, data=payload)
    udp.ulen = len(udp)  # pyright: ignore[reportAttributeAccessIssue]
    ip = dpkt.ip.IP(
        src=bytes([192, 168, 1, 201]),
        dst=b"\xff" * 4,
        p=dpkt.ip.IP_PROTO_UDP,
        ttl=64,
        id=ip_id & 0xFFFF,
        data=udp,
    )
    ip.len = len(ip)
    eth = dpkt.ethernet.Ethernet(
        src=bytes.fromhex("60768800a1b2"), dst=b"\xff" * 6, type=dpkt.ethernet.ETH_TYPE_IP, data=ip
    )
    return bytes(eth)


def write_velodyne_pcap(
    path: str | Path, packets: np.ndarray, packet_times: np.ndarray, *, port: int = 2368
) -> None:
    """Write data packets to a libpcap capture as a laptop records them: one `udp_frame` per
    packet, stamped with its `packet_times` entry.

    packets : (p, 1206) uint8 payloads; packet_times : (p,) UNIX s. Needs dpkt (the `sim`
    extra). Raises ValueError when the shapes disagree.
    """
    import dpkt

    packets = np.asarray(packets)
    if packets.dtype.kind not in "iu" or (
        packets.size and not 0 <= packets.min() <= packets.max() <= 255
    ):
        raise ValueError("packets: expected bytes (integers in [0, 255])")
    packets = packets.astype(np.uint8)
    times = as_float_array("packet_times", packet_times)
    port = integer("port", port, low=0, high=65535)
    if packets.ndim != 2 or packets.shape[1] != PACKET_SIZE or times.shape != packets.shape[:1]:
        raise ValueError(
            f"packets, packet_times: expected (p, {PACKET_SIZE}) and (p,), got "
            f"{packets.shape} and {times.shape}"
        )
    with open(path, "wb") as fh:
        writer = dpkt.pcap.Writer(fh, snaplen=1600, linktype=dpkt.pcap.DLT_EN10MB)
        for k, (row, t) in enumerate(zip(packets, times.tolist(), strict=True)):
            writer.writepkt(udp_frame(row.tobytes(), port, k), ts=t)
