"""Camera: calibration, detection (YOLO through torch), filters, and georeferencing onto the
water plane with per-detection covariance. See the submodules for details."""

from usvfast.camera.georef import (
    REASONS,
    FovCamera,
    Georeferenced,
    Sensitivity,
    box_contact_points,
    georeference,
    georeference_fov,
    mount_rotation,
    rotation_zyx,
    sensitivity,
)
from usvfast.camera.nms import nms

__all__ = [
    "REASONS",
    "FovCamera",
    "Georeferenced",
    "Sensitivity",
    "box_contact_points",
    "georeference",
    "georeference_fov",
    "mount_rotation",
    "nms",
    "rotation_zyx",
    "sensitivity",
]
