"""Damaged ROS bags of real Velodyne packets: nothing a complete chunk/row/record holds is lost.

The bags hold VelodyneScan messages of the real capture's packets (tests/data/lidar), one
scan per 5 packets. Each damaged bag is compared frame by frame with the intact one.
"""

from __future__ import annotations

import shutil
import warnings
from pathlib import Path

import numpy as np
import pytest
from rosbags.rosbag1 import Writer as Writer1
from rosbags.rosbag2 import StoragePlugin
from rosbags.rosbag2 import Writer as Writer2
from test_lidar_readers import real_packets, scan_message

from usvfast._damage import DamagedRecordsWarning
from usvfast.lidar import BagReader, open_lidar
from usvfast.lidar.readers import lidar_typestore
from usvfast.nav.bags import bag_topics

MSGTYPE = "velodyne_msgs/msg/VelodyneScan"


def write_bag(path: Path, *, ros1: bool, chunk: int | None = None, compression=None, mcap=False):
    """Scans of 5 real packets each; ROS 1 chunks of about `chunk` bytes."""
    packets = real_packets()
    scans = [packets[i : i + 5] for i in range(0, len(packets), 5)]
    store = lidar_typestore(ros1)
    if ros1:
        writer = Writer1(path)
        if compression:
            writer.set_compression(compression)
        if chunk:
            writer.chunk_threshold = chunk
        ser = store.serialize_ros1
    else:
        plugin = StoragePlugin.MCAP if mcap else StoragePlugin.SQLITE3
        writer = Writer2(path, version=8, storage_plugin=plugin)
        ser = store.serialize_cdr
    with writer:
        conn = writer.add_connection("/velodyne_packets", MSGTYPE, typestore=store)
        for pk in scans:
            stamp = pk[-1][0]
            writer.write(conn, int(stamp * 1e9), ser(scan_message(store, pk, stamp), MSGTYPE))
    return path


def frames_of(path: Path, **kw):
    reader = BagReader(path, **kw)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        frames = list(reader)
    return frames, reader, [w for w in caught if issubclass(w.category, DamagedRecordsWarning)]


def assert_prefix_of(frames, intact):
    """Every recovered frame equals the intact frame of the same stamp."""
    by_stamp = {f.stamp: f for f in intact}
    for f in frames:
        np.testing.assert_array_equal(f.points, by_stamp[f.stamp].points)


@pytest.fixture(scope="module")
def intact(tmp_path_factory):
    path = write_bag(tmp_path_factory.mktemp("intact") / "a.bag", ros1=True)
    frames, _, caught = frames_of(path)
    assert not caught and len(frames) == 17
    return frames


def test_ros1_bag_cut_by_one_byte_loses_nothing(tmp_path, intact):
    data = write_bag(tmp_path / "a.bag", ros1=True).read_bytes()
    cut = tmp_path / "cut.bag"
    cut.write_bytes(data[:-1])  # the index at the end is cut: AnyReader refuses the bag
    frames, reader, caught = frames_of(cut)
    assert len(caught) == 1 and "recovered 17 message(s)" in str(caught[0].message)
    assert len(frames) == 17 and reader.stats.damaged == 0
    assert_prefix_of(frames, intact)


@pytest.mark.parametrize("compression", [None, Writer1.CompressionFormat.BZ2])
def test_ros1_bag_cut_mid_chunk_keeps_every_complete_chunk(tmp_path, intact, compression):
    path = write_bag(tmp_path / "a.bag", ros1=True, chunk=20_000, compression=compression)
    data = path.read_bytes()
    cut = tmp_path / "cut.bag"
    cut.write_bytes(data[: len(data) // 2])
    frames, reader, _ = frames_of(cut)
    assert 4 <= len(frames) < 17
    if compression is None:  # an uncompressed cut chunk keeps its complete messages too
        assert len(frames) >= 8
    assert reader.stats.reasons["bag container"] == 1
    assert [f.stamp for f in frames] == [f.stamp for f in intact[: len(frames)]]
    assert_prefix_of(frames, intact)


def test_ros1_cut_bag_through_the_nav_reader(tmp_path):
    data = write_bag(tmp_path / "a.bag", ros1=True).read_bytes()
    cut = tmp_path / "cut.bag"
    cut.write_bytes(data[:-7])
    with pytest.warns(DamagedRecordsWarning, match="damaged bag"):
        topics = bag_topics(cut)
    assert topics["/velodyne_packets"].count == 17


def test_ros2_sqlite_truncated_reads_every_readable_row(tmp_path, intact):
    path = write_bag(tmp_path / "b", ros1=False)
    db = next(path.glob("*.db3"))
    data = db.read_bytes()
    db.write_bytes(data[: int(len(data) * 0.6)])
    frames, _, caught = frames_of(path)
    assert caught and "damaged bag" in str(caught[0].message)
    assert 3 <= len(frames) < 17
    assert_prefix_of(frames, intact)


def test_ros2_folder_without_metadata_is_read_from_the_database(tmp_path, intact):
    path = write_bag(tmp_path / "b", ros1=False)
    (path / "metadata.yaml").unlink()
    frames, _, caught = frames_of(path)
    assert caught and "recovered 17 message(s)" in str(caught[0].message)
    assert len(frames) == 17
    assert_prefix_of(frames, intact)


@pytest.mark.parametrize("keep", [0.999, 0.6])
def test_mcap_without_summary(tmp_path, intact, keep):
    path = write_bag(tmp_path / "m", ros1=False, mcap=True)
    mcap = next(path.glob("*.mcap"))
    data = mcap.read_bytes()
    mcap.write_bytes(data[: int(len(data) * keep)])  # no footer, no summary
    frames, _, caught = frames_of(path)
    assert caught
    assert len(frames) >= (15 if keep > 0.9 else 3)
    assert_prefix_of(frames, intact)


def test_folder_with_nothing_says_what_is_missing(tmp_path):
    (tmp_path / "empty").mkdir()
    with pytest.raises(ValueError, match=r"no metadata.yaml and no \.db3 or \.mcap"):
        list(open_lidar(tmp_path / "empty"))


def test_garbage_bag_is_a_value_error(tmp_path):
    bad = tmp_path / "x.bag"
    bad.write_bytes(b"#ROSBAG V2.0\n" + b"\xff" * 100)
    with pytest.raises(ValueError):
        list(BagReader(bad))
    shutil.rmtree(tmp_path / "x.bag", ignore_errors=True)
