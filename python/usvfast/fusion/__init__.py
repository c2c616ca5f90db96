"""Radar + AIS (+ camera) fusion for a ship's bridge or a VTS centre: AIS feeds with receive
times, AIS targets interpolated at radar scan times, radar ↔ AIS association (the radar/AIS
paper's J and a χ² track-to-track test), covariance intersection, visual matching in the
camera, and the camera ↔ VTS rotation from matched velocities."""

from usvfast.fusion.ais_feed import AisFeed, AisStates, AisTargets, read_ais_feed
from usvfast.fusion.associate import (
    Chi2Test,
    JCost,
    WindowAssociator,
    covariance_intersection,
    same_object,
)
from usvfast.fusion.pipeline import FusedRow, OwnShip, TrackerConfig, VtsResult, run_vts
from usvfast.fusion.rotation import RotationCalibrator, rotation_from_velocities
from usvfast.fusion.visual import Projection, match_detections, project_targets

__all__ = [
    "AisFeed",
    "AisStates",
    "AisTargets",
    "Chi2Test",
    "FusedRow",
    "JCost",
    "OwnShip",
    "Projection",
    "RotationCalibrator",
    "TrackerConfig",
    "VtsResult",
    "WindowAssociator",
    "covariance_intersection",
    "match_detections",
    "project_targets",
    "read_ais_feed",
    "rotation_from_velocities",
    "run_vts",
    "same_object",
]
