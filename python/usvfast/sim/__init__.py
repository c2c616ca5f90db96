"""A simulated harbour recording for the thesis's system (LiDAR + camera + GNSS on a USV):
the scene and its motion (`scene`, `motion`), the VLP-16 packets (`velodyne`), the camera
images (`camera`), the GNSS/heading NMEA and the IMU (`gnss`), what each sensor physically
saw of every object (`visibility`), and the writers of the rosbag2 and the thesis's D1 layout
(`recording`). `usvfast simulate` runs it.

Units are metres, seconds and radians (`_deg` names excepted); the world frame is local NED
around the USV's start point; times in the recordings are UNIX seconds.
"""

from usvfast.sim.camera import HarbourRenderer, PixelBox, default_camera, render_frame
from usvfast.sim.scene import FLOAT_KINDS, TRUTH_KINDS, World, make_world

__all__ = [
    "FLOAT_KINDS",
    "TRUTH_KINDS",
    "HarbourRenderer",
    "PixelBox",
    "World",
    "default_camera",
    "make_world",
    "render_frame",
]
