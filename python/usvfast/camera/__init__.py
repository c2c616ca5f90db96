"""Camera: calibration, detection, filters, and georeferencing onto the water plane with
per-detection covariance. See the submodules for details. Detector backends share
`usvfast.camera.detect` (letterbox, YOLO decoding, NMS): `usvfast.camera.dnn.OnnxDetector`
(ONNX through OpenCV DNN) and `usvfast.camera.yolo.YoloDetector` (torch, optional dependency);
`usvfast.camera.backends.load_detector` picks one by name, and `usvfast.camera.chain.CameraPipeline`
chains either with the filters and georeferencing. They are not imported here."""

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
