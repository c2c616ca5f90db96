"""A pipeline config for the navigation tests: the `[recording]` lines and stream tables a test
gives, plus a LiDAR stream from an empty pcap (a config needs one sensor). Not part of the
library."""

from __future__ import annotations

from pathlib import Path


def nav_config(tmp_path: Path, recording: str, streams: str) -> Path:
    """Write tmp_path/nav.toml with `recording` under [recording] and the `streams` tables;
    returns its path."""
    path = tmp_path / "nav.toml"
    path.write_text(
        f"""
[recording]
{recording}
{streams}
[[stream]]
id = "lidar"
type = "pcap"
path = "none.pcap"
sensor = "lidar"
[lidar]
waterline_height = 0.3
"""
    )
    (tmp_path / "none.pcap").write_bytes(b"")
    return path
