"""Navigation data: readers for field recordings (NMEA, AIS, GPX, ROS bags, video), the vessel
pose over time, and time-synchronised replay of multi-sensor recordings."""
