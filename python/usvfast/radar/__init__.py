"""Radar as a sensor: plots from CSV, NMEA ARPA sentences (TTM/TLL) or NED recordings, and log
clocks (tag blocks, leading time columns, ZDA/RMC) shared with the AIS feed reader."""

from usvfast.nav.linetime import LogClock, tag_block_ok
from usvfast.radar.readers import RadarPlots, plots_from_ned, read_radar_csv, read_radar_nmea

__all__ = [
    "LogClock",
    "RadarPlots",
    "plots_from_ned",
    "read_radar_csv",
    "read_radar_nmea",
    "tag_block_ok",
]
