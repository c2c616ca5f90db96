"""Eq. (1) of Gorad, Hassan & Särkkä (SCIA 2023): pixel centre of a detection box -> bearing
and elevation relative to own heading, and its exact inverse.

Angles are degrees (every angle name ends in `_deg`), pixels are `_px`. With the image
x axis to the right and y down (OpenCV), eq. (1) reads

    [β, ψ]ᵀ = (1/γ) · [[cos θh, sin θh], [-sin θh, cos θh]]
              · [atan(2 tan(f_x/2) (x/W - 0.5)) + θp, atan(2 tan(f_y/2) (y/H - 0.5)) + θt]ᵀ
              + [θ0, θε]ᵀ

so β grows clockwise (to the right in the image: starboard of the camera axis, seen from
above) and ψ grows downward in the image (a target lower in the picture has a larger ψ).
θh is the horizon roll measured clockwise in the image, (θp, γ, θt) pan, zoom and tilt,
(θ0, θε) the azimuth/elevation mounting offsets relative to own heading.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from usvfast._validate import broadcast, instance, real
from usvfast.bearing.angles import float_array


@dataclass(frozen=True)
class BearingCamera:
    """Calibration of one camera for eq. (1).

    width_px, height_px: image size W, H (pixels). hfov_deg, vfov_deg: horizontal and vertical
    field of view f_x, f_y (degrees, in (0, 180)). azimuth_offset_deg θ0 and
    elevation_offset_deg θε: mounting offsets relative to own heading (degrees, clockwise /
    downward positive). horizon_roll_deg θh: horizon angle measured clockwise in the image.
    pan_deg θp, tilt_deg θt, zoom γ (> 0): default pan-tilt-zoom, overridable per box.
    Raises ValueError naming the field when a value is out of range or not finite.
    """

    width_px: float
    height_px: float
    hfov_deg: float
    vfov_deg: float
    azimuth_offset_deg: float = 0.0
    elevation_offset_deg: float = 0.0
    horizon_roll_deg: float = 0.0
    pan_deg: float = 0.0
    tilt_deg: float = 0.0
    zoom: float = 1.0

    def __post_init__(self) -> None:
        for name, value in asdict(self).items():
            if not isinstance(value, int | float) or not math.isfinite(value):
                raise ValueError(f"{name}: expected a finite number, got {value!r}")
        for name in ("width_px", "height_px", "zoom"):
            if getattr(self, name) <= 0:
                raise ValueError(f"{name}: must be > 0, got {getattr(self, name)}")
        for name in ("hfov_deg", "vfov_deg"):
            if not 0.0 < getattr(self, name) < 180.0:
                raise ValueError(f"{name}: must be in (0, 180) degrees, got {getattr(self, name)}")

    @classmethod
    def from_dict(cls, values: dict[str, Any]) -> BearingCamera:
        """Build from a mapping of field names (e.g. one entry of a cameras JSON file).

        When `vfov_deg` is missing it is derived from `hfov_deg` and the aspect ratio
        (square pixels: tan(f_y/2) = tan(f_x/2)·H/W). Unknown keys raise ValueError.
        """
        values = dict(values)
        unknown = set(values) - set(cls.__dataclass_fields__)
        if unknown:
            raise ValueError(f"camera: unknown field(s) {sorted(unknown)}")
        if "vfov_deg" not in values and {"hfov_deg", "width_px", "height_px"} <= set(values):
            values["vfov_deg"] = square_pixel_vfov_deg(
                values["hfov_deg"], values["width_px"], values["height_px"]
            )
        try:
            return cls(**values)
        except TypeError as exc:
            raise ValueError(f"camera: {exc}") from exc

    def to_dict(self) -> dict[str, float]:
        """The fields as a plain dict (JSON-ready)."""
        return asdict(self)


def square_pixel_vfov_deg(hfov_deg: float, width_px: float, height_px: float) -> float:
    """Vertical field of view (degrees) of a pinhole camera with square pixels. `hfov_deg` in
    (0, 180), `width_px` and `height_px` > 0; else ValueError naming the argument."""
    hfov_deg = real("hfov_deg", hfov_deg, positive=True)
    if not hfov_deg < 180.0:
        raise ValueError(f"hfov_deg: must be < 180, got {hfov_deg}")
    width_px = real("width_px", width_px, positive=True)
    height_px = real("height_px", height_px, positive=True)
    return math.degrees(
        2.0 * math.atan(math.tan(math.radians(hfov_deg) / 2.0) * height_px / width_px)
    )


# The paper's calibration (Sect. 2.3): FLIR Blackfly 1920x1200 visible camera, f_x = 20.0°,
# θ0 = -61.8°, θε = 3.5°, θh = -1.55°, no pan; FLIR M232 320x240 thermal camera, f_x = 19°,
# θ0 = -79.2°, θε = 2.7°, no horizon roll (its pan comes per frame from the image data).
# The paper gives no vertical FoV: it is derived for square pixels.
VISIBLE_CAMERA = BearingCamera(
    width_px=1920,
    height_px=1200,
    hfov_deg=20.0,
    vfov_deg=square_pixel_vfov_deg(20.0, 1920, 1200),
    azimuth_offset_deg=-61.8,
    elevation_offset_deg=3.5,
    horizon_roll_deg=-1.55,
)
THERMAL_CAMERA = BearingCamera(
    width_px=320,
    height_px=240,
    hfov_deg=19.0,
    vfov_deg=square_pixel_vfov_deg(19.0, 320, 240),
    azimuth_offset_deg=-79.2,
    elevation_offset_deg=2.7,
    horizon_roll_deg=0.0,
)


class BearingElevation(NamedTuple):
    """Bearing β and elevation ψ (degrees) relative to own heading, arrays of one shape."""

    bearing_deg: np.ndarray
    elevation_deg: np.ndarray


class PixelPoint(NamedTuple):
    """Pixel coordinates (x right, y down) of box centres, arrays of one shape."""

    x_px: np.ndarray
    y_px: np.ndarray


def _ptz(
    camera: BearingCamera, pan_deg: Any, tilt_deg: Any, zoom: Any
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    pan = float_array("pan_deg", camera.pan_deg if pan_deg is None else pan_deg)
    tilt = float_array("tilt_deg", camera.tilt_deg if tilt_deg is None else tilt_deg)
    gamma = float_array("zoom", camera.zoom if zoom is None else zoom)
    if np.any(gamma <= 0):
        raise ValueError("zoom: must be > 0")
    return pan, tilt, gamma


def pixel_to_bearing(
    x_px: ArrayLike,
    y_px: ArrayLike,
    camera: BearingCamera,
    *,
    pan_deg: Any = None,
    tilt_deg: Any = None,
    zoom: Any = None,
) -> BearingElevation:
    """Eq. (1): box centres (x_px, y_px) -> bearing and elevation (degrees) w.r.t. own heading.

    x_px, y_px: pixel coordinates, any broadcastable shapes. pan_deg, tilt_deg, zoom: per-box
    pan-tilt-zoom (broadcastable), default the camera's. Bearing is clockwise positive
    (starboard), not wrapped. Raises NonFiniteError/ValueError naming the argument.
    """
    instance("camera", camera, BearingCamera)
    x = float_array("x_px", x_px)
    y = float_array("y_px", y_px)
    pan, tilt, gamma = _ptz(camera, pan_deg, tilt_deg, zoom)
    x, y, pan, tilt, gamma = broadcast(
        {"x_px": x, "y_px": y, "pan_deg": pan, "tilt_deg": tilt, "zoom": gamma}
    )
    tan_half_fx = math.tan(math.radians(camera.hfov_deg) / 2.0)
    tan_half_fy = math.tan(math.radians(camera.vfov_deg) / 2.0)
    # angles in the camera: atan(2 tan(f/2) (x/W - 0.5)) + pan/tilt
    u = np.degrees(np.arctan(2.0 * tan_half_fx * (x / camera.width_px - 0.5))) + pan
    v = np.degrees(np.arctan(2.0 * tan_half_fy * (y / camera.height_px - 0.5))) + tilt
    c = math.cos(math.radians(camera.horizon_roll_deg))
    s = math.sin(math.radians(camera.horizon_roll_deg))
    # (1/γ) R(θh) [u, v] + [θ0, θε]
    bearing = (c * u + s * v) / gamma + camera.azimuth_offset_deg
    elevation = (-s * u + c * v) / gamma + camera.elevation_offset_deg
    return BearingElevation(bearing, elevation)


def bearing_to_pixel(
    bearing_deg: ArrayLike,
    elevation_deg: ArrayLike,
    camera: BearingCamera,
    *,
    pan_deg: Any = None,
    tilt_deg: Any = None,
    zoom: Any = None,
) -> PixelPoint:
    """Inverse of eq. (1): bearing/elevation (degrees w.r.t. own heading) -> pixel (x, y).

    Exact inverse of `pixel_to_bearing` with the same camera and pan-tilt-zoom. The bearing is
    taken as given (not wrapped), so pass it on the camera's side of ±180°. Points more than
    90° off the optical axis (after un-rotating) have no image and come back as NaN; points
    outside the frame come back with coordinates outside [0, W] x [0, H].
    """
    instance("camera", camera, BearingCamera)
    b = float_array("bearing_deg", bearing_deg)
    e = float_array("elevation_deg", elevation_deg)
    pan, tilt, gamma = _ptz(camera, pan_deg, tilt_deg, zoom)
    b, e, pan, tilt, gamma = broadcast(
        {"bearing_deg": b, "elevation_deg": e, "pan_deg": pan, "tilt_deg": tilt, "zoom": gamma}
    )
    c = math.cos(math.radians(camera.horizon_roll_deg))
    s = math.sin(math.radians(camera.horizon_roll_deg))
    db = gamma * (b - camera.azimuth_offset_deg)
    de = gamma * (e - camera.elevation_offset_deg)
    # R(θh)ᵀ undoes the rotation: [u, v] = γ Rᵀ ([β, ψ] - [θ0, θε])
    u = c * db - s * de - pan
    v = s * db + c * de - tilt
    tan_half_fx = math.tan(math.radians(camera.hfov_deg) / 2.0)
    tan_half_fy = math.tan(math.radians(camera.vfov_deg) / 2.0)
    with np.errstate(invalid="ignore"):
        ok = (np.abs(u) < 90.0) & (np.abs(v) < 90.0)
        x = np.where(
            ok, camera.width_px * (0.5 + np.tan(np.radians(u)) / (2.0 * tan_half_fx)), np.nan
        )
        y = np.where(
            ok, camera.height_px * (0.5 + np.tan(np.radians(v)) / (2.0 * tan_half_fy)), np.nan
        )
    return PixelPoint(x, y)
