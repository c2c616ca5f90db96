"""Radar as a sensor: plots from CSV, NMEA ARPA sentences (TTM/TLL) or NED recordings, log
clocks (tag blocks, leading time columns, ZDA/RMC) shared with the AIS feed reader, and the
radar's alignment (bearing bias) calibrated against a reference track."""

from usvfast.nav.linetime import LogClock, tag_block_ok
from usvfast.radar.alignment import bearing_bias_deg
from usvfast.radar.readers import RadarPlots, plots_from_ned, read_radar_csv, read_radar_nmea

__all__ = [
    "LogClock",
    "RadarPlots",
    "bearing_bias_deg",
    "plots_from_ned",
    "read_radar_csv",
    "read_radar_nmea",
    "tag_block_ok",
]
