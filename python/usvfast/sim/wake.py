"""Bow waves and wakes of vessels under way, as foam on the water of the rendered frames.

A hull moving through the water pushes up a bow wave along its forward sides and leaves a
turbulent white trail behind its stern, flanked by the two arms of the Kelvin wedge at
±19.47° (arcsin 1/3) to its track; a moored boat has neither. The foam is a coverage
fraction 0..1 of each point of the water surface, computed in the vessel's own frame (x
forward along its heading, y to starboard, m) from its speed: the trail is
`TRAIL_SECONDS` × speed long and the foam's brightness grows with speed up to
`FULL_FOAM_SPEED`. The white water that rises above the surface (the bow wave's crest,
the wash at the transom) is drawn as low foam boxes around the hull (`splash_boxes`). The
renderer paints the foam on the water pixels (where the pixel's ray meets the sea), so the
wake moves with the camera's roll and pitch and is hidden by any body in front of it, the
vessel's own hull included.
"""

from __future__ import annotations

import numpy as np

from usvfast.lidar.simulator import Box
from usvfast.sim.scene import Mover

#: Length of the stern trail and of the Kelvin arms per m/s of speed, s.
TRAIL_SECONDS = 3.0
#: Speed from which the foam is at full brightness, m/s; below `MIN_SPEED` there is none.
FULL_FOAM_SPEED = 2.0
MIN_SPEED = 0.3
#: Foam colour, BGR.
FOAM = np.array([238.0, 242.0, 240.0], dtype=np.float32)
_KELVIN = np.tan(np.arcsin(1.0 / 3.0))


def mover_speed(mover: Mover, t: float, dt: float = 0.05) -> float:
    """Speed over ground of `mover` at time `t` s (central difference over ±`dt` s), m/s."""
    n, e, _ = mover.motion.pose(np.array([t - dt, t + dt]))
    return float(np.hypot(n[1] - n[0], e[1] - e[0]) / (2 * dt))


def foam(x: np.ndarray, y: np.ndarray, *, length: float, beam: float, speed: float) -> np.ndarray:
    """Foam coverage 0..1 (k,) at points (x, y) (k,) m in the frame of a hull of `length` ×
    `beam` m centred at the origin, heading +x at `speed` m/s."""
    x = np.asarray(x, dtype=np.float32)
    ay = np.abs(np.asarray(y, dtype=np.float32))
    out = np.zeros(x.shape, dtype=np.float32)
    if speed < MIN_SPEED:
        return out
    gain = np.float32(min(speed / FULL_FOAM_SPEED, 1.0))
    trail = np.float32(TRAIL_SECONDS * speed)
    half = np.float32(beam / 2)
    # stern trail: behind the transom, widening and fading with distance u
    u = np.float32(-length / 2) - x
    behind = (u >= 0) & (u <= trail)
    u = np.clip(u, 0.0, trail)  # (the bands below are kept only behind the transom)
    width = half * (0.8 + 0.12 * u)
    core = np.clip(1.0 - (ay / width) ** 2, 0.0, 1.0) * np.exp(-u / (0.6 * trail))
    out = np.where(behind, np.maximum(out, 0.9 * core), out)
    # Kelvin arms: thin bands from the stern quarters at arctan(1/sqrt(8)) to the track
    off = np.abs(ay - (half + _KELVIN * u))
    arm = np.clip(1.0 - off / 0.3, 0.0, 1.0) * np.exp(-u / (0.5 * trail))
    out = np.where(behind, np.maximum(out, 0.7 * arm), out)
    # bow wave: a band along the forward half of each side and around the stem
    fwd = (x > 0) & (x < length / 2 + 0.5)
    band = np.float32(0.35 + 0.15 * speed)
    side = np.clip(1.0 - np.abs(ay - half - 0.5 * band) / (0.5 * band), 0.0, 1.0)
    side *= np.clip(x / (0.25 * length), 0.0, 1.0)
    out = np.where(fwd & (ay < half + band), np.maximum(out, side), out)
    return np.clip(out * gain, 0.0, 1.0)


def splash_boxes(mover: Mover, t: float) -> list[Box]:
    """The white water that rises above the surface around a hull under way, as low boxes in
    the world frame at time `t` s: the bow wave along the forward 40 % of the sides
    (0.12 + 0.1 × speed m high) and the churned wash behind the transom (0.12 + 0.08 × speed
    m high, 0.8 × speed m long). None below `MIN_SPEED`."""
    speed = mover_speed(mover, t)
    if speed < MIN_SPEED:
        return []
    length, beam, _ = mover.size
    n, e, yaw = (float(v) for v in mover.motion.pose(np.asarray(t)))
    c, s = np.cos(yaw), np.sin(yaw)
    out = []
    for x, box_length, box_beam, top in (
        (length * 0.3, length * 0.4, beam + 0.3, 0.12 + 0.1 * speed),
        (-length / 2 - 0.4 * speed, 0.8 * speed, beam * 0.9, 0.12 + 0.08 * speed),
    ):
        out.append(Box((n + c * x, e + s * x), box_length, box_beam, yaw, 0.0, top))
    return out


def texture(north: np.ndarray, east: np.ndarray, t: float) -> np.ndarray:
    """Foam breakup 0.55..1 (k,) at world points (m), slowly changing with time `t` s."""
    a = np.sin(2.7 * north + 1.9 * east + 1.3 * t) * np.sin(3.4 * east - 2.2 * north - 0.9 * t)
    return (0.775 + 0.225 * a).astype(np.float32)


def wake_extent(length: float, beam: float, speed: float) -> tuple[float, float, float]:
    """(forward end, aft end, half width) m of the region where `foam` can be non-zero, in
    the hull's frame."""
    trail = TRAIL_SECONDS * max(speed, 0.0)
    fwd = length / 2 + 0.5
    aft = -length / 2 - trail
    half = beam / 2 + max(_KELVIN * trail + 0.3, 0.35 + 0.15 * speed)
    return fwd, aft, half


__all__ = [
    "FOAM",
    "FULL_FOAM_SPEED",
    "MIN_SPEED",
    "TRAIL_SECONDS",
    "foam",
    "mover_speed",
    "splash_boxes",
    "texture",
    "wake_extent",
]
