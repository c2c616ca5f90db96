"""LiDAR floating-object detection (thesis section 3.3): readers, water geometry, the
prefilter -> LSD lines -> line memory -> line-of-sight -> buffered mean shift chain, and a
VLP-16 scan simulator. The Rust hot paths are the line-of-sight filter
(`line_of_sight_filter`) and the flat-kernel mean shift.

Units are metres and radians (`_deg` names excepted), times UNIX seconds; sensor-frame
points are Velodyne's (x forward, y left, z up), world points NED (north, east).
"""

from usvfast.lidar.clustering import mean_shift
from usvfast.lidar.detections import LidarDetection, cluster_detections, near_median
from usvfast.lidar.evaluation import SceneScore, evaluate_scene, straight_run
from usvfast.lidar.frame import POINT_DTYPE, LidarFrame, make_points
from usvfast.lidar.geometry import dead_zone_radius, downward_angles_deg, water_geometry
from usvfast.lidar.line_of_sight import (
    line_of_sight_filter,
    line_of_sight_filter_naive,
    line_of_sight_filter_numpy,
)
from usvfast.lidar.lines import (
    LineMemory,
    blur,
    covered_mask,
    detect_segments,
    drop_covered,
    extend_segments,
    move_segments,
    point_segment_distance,
    rasterize,
)
from usvfast.lidar.packets import LidarDataWarning, ReadStats
from usvfast.lidar.pcap import VelodynePcapReader
from usvfast.lidar.pipeline import (
    CycleResult,
    FrameResult,
    LidarConfig,
    LidarDetector,
    prefilter,
    sensor_motion,
    sensor_to_world,
    world_to_sensor,
)
from usvfast.lidar.readers import (
    BagReader,
    open_lidar,
    pointcloud2_to_points,
    write_pointcloud2_bag,
)
from usvfast.lidar.simulator import (
    Box,
    Cylinder,
    Scene,
    SimulatedFrame,
    VLP16Simulator,
    Wall,
    harbour_scene,
)

__all__ = [
    "POINT_DTYPE",
    "BagReader",
    "Box",
    "CycleResult",
    "Cylinder",
    "FrameResult",
    "LidarConfig",
    "LidarDataWarning",
    "LidarDetection",
    "LidarDetector",
    "LidarFrame",
    "LineMemory",
    "ReadStats",
    "Scene",
    "SceneScore",
    "SimulatedFrame",
    "VLP16Simulator",
    "VelodynePcapReader",
    "Wall",
    "blur",
    "cluster_detections",
    "covered_mask",
    "dead_zone_radius",
    "detect_segments",
    "downward_angles_deg",
    "drop_covered",
    "evaluate_scene",
    "extend_segments",
    "harbour_scene",
    "line_of_sight_filter",
    "line_of_sight_filter_naive",
    "line_of_sight_filter_numpy",
    "make_points",
    "mean_shift",
    "move_segments",
    "near_median",
    "open_lidar",
    "point_segment_distance",
    "pointcloud2_to_points",
    "prefilter",
    "rasterize",
    "sensor_motion",
    "sensor_to_world",
    "straight_run",
    "water_geometry",
    "world_to_sensor",
    "write_pointcloud2_bag",
]
