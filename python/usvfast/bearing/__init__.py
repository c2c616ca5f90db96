"""Vessel bearing estimation from visible and thermal cameras, fused with a Kalman filter
and RTS smoother and checked against AIS (Gorad, Hassan & Särkkä, SCIA 2023).

Units: this package follows the paper and works in degrees. Every angle argument, field and
CSV column ends in `_deg` (rates `_deg_s`, pixels `_px`); the process noise q is
`noise_diff_coeff_deg2` (deg²/s³). Bearings are relative to own heading, positive clockwise
(to starboard), wrapped to (-180°, 180°]. Times are UNIX seconds.

- eq. (1): `pixel_to_bearing` / `bearing_to_pixel` with a `BearingCamera` calibration
  (`VISIBLE_CAMERA`, `THERMAL_CAMERA` hold the paper's values);
- eq. (2): `relative_bearing_deg`, and `reference_bearing_deg` along `VesselTrack`s;
- fusion: `fuse_bearings` -> `BearingFusion`; evaluation: `bearing_rmse_table`;
- I/O: `read_bearing_samples`, `read_ais`; sample data: `generate_encounter`.
"""

from usvfast.bearing.ais import (
    VesselTrack,
    ais_report_interval_s,
    great_circle_bearing_deg,
    reference_bearing_deg,
    relative_bearing_deg,
)
from usvfast.bearing.angles import unwrap_deg, wrap_deg
from usvfast.bearing.camera import (
    THERMAL_CAMERA,
    VISIBLE_CAMERA,
    BearingCamera,
    BearingElevation,
    PixelPoint,
    bearing_to_pixel,
    pixel_to_bearing,
)
from usvfast.bearing.fusion import (
    PAPER_MEASUREMENT_STD_DEG,
    PAPER_NOISE_DIFF_COEFF_DEG2,
    SOURCE_NAMES,
    THERMAL,
    VISIBLE,
    BearingFusion,
    RmseRow,
    bearing_rmse_table,
    fuse_bearings,
    rmse_deg,
)

__all__ = [
    "PAPER_MEASUREMENT_STD_DEG",
    "PAPER_NOISE_DIFF_COEFF_DEG2",
    "SOURCE_NAMES",
    "THERMAL",
    "THERMAL_CAMERA",
    "VISIBLE",
    "VISIBLE_CAMERA",
    "BearingCamera",
    "BearingElevation",
    "BearingFusion",
    "PixelPoint",
    "RmseRow",
    "VesselTrack",
    "ais_report_interval_s",
    "bearing_rmse_table",
    "bearing_to_pixel",
    "fuse_bearings",
    "great_circle_bearing_deg",
    "pixel_to_bearing",
    "reference_bearing_deg",
    "relative_bearing_deg",
    "rmse_deg",
    "unwrap_deg",
    "wrap_deg",
]
