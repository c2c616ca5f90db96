"""Camera: calibration, detection (YOLO through torch), filters, and georeferencing onto the
water plane with per-detection covariance. See the submodules for details; the YOLO wrapper
(`usvfast.camera.yolo`) needs the optional torch dependency and is not imported here."""

from usvfast.camera.calibration import CalibrationResult, CameraModel, calibrate
from usvfast.camera.georef import (
    REASONS,
    FovCamera,
    Georeferenced,
    Sensitivity,
    box_contact_points,
    georeference,
    georeference_fov,
    horizon_line,
    mount_rotation,
    rotation_zyx,
    sensitivity,
)
from usvfast.camera.nms import nms

__all__ = [
    "REASONS",
    "CalibrationResult",
    "CameraModel",
    "FovCamera",
    "Georeferenced",
    "Sensitivity",
    "box_contact_points",
    "calibrate",
    "georeference",
    "georeference_fov",
    "horizon_line",
    "mount_rotation",
    "nms",
    "rotation_zyx",
    "sensitivity",
]
