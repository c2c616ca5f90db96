"""Radar as a sensor: plots from CSV, NMEA ARPA sentences (TTM/TLL) or NED recordings, log
clocks (tag blocks, leading time columns, ZDA/RMC) shared with the AIS feed reader, and the
radar's alignment (bearing bias) calibrated against a reference track, and the tracker's
plot, clutter and process noise estimated from such a calibration run."""

from usvfast.nav.linetime import LogClock, tag_block_ok
from usvfast.radar.alignment import bearing_bias_deg
from usvfast.radar.calibration import (
    CvNoiseMixture,
    PlotStatistics,
    TurnNoise,
    cv_noise_mixture,
    plot_statistics,
    turn_noise,
)
from usvfast.radar.readers import RadarPlots, plots_from_ned, read_radar_csv, read_radar_nmea

__all__ = [
    "CvNoiseMixture",
    "LogClock",
    "PlotStatistics",
    "RadarPlots",
    "TurnNoise",
    "bearing_bias_deg",
    "cv_noise_mixture",
    "plot_statistics",
    "plots_from_ned",
    "read_radar_csv",
    "read_radar_nmea",
    "tag_block_ok",
    "turn_noise",
]
