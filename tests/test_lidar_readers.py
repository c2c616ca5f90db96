"""LiDAR readers on the real HDL-32E capture, on damaged copies of it, and on ROS bags."""

from __future__ import annotations

import struct
import warnings
from pathlib import Path

import dpkt
import numpy as np
import pytest
import velodyne_decoder as vd

from usvfast.lidar import (
    POINT_DTYPE,
    BagReader,
    LidarDataWarning,
    VelodynePcapReader,
    open_lidar,
    write_pointcloud2_bag,
)
from usvfast.lidar.packets import velodyne_packet_problem
from usvfast.lidar.readers import lidar_typestore, make_header, pointcloud2_to_points

from conftest import SHARED_DATA

PCAP = SHARED_DATA / "lidar" / "velodyne_hdl32e.pcap"


def records(data: bytes) -> list[tuple[int, int]]:
    """(offset, total length incl. the 16-byte header) of every record of a clean pcap."""
    out, pos = [], 24
    while pos < len(data):
        incl = struct.unpack_from("<I", data, pos + 8)[0]
        out.append((pos, 16 + incl))
        pos += 16 + incl
    return out


def without(data: bytes, drop: set[int]) -> bytes:
    """The pcap with the records of the given indices removed."""
    recs = records(data)
    return data[:24] + b"".join(data[o : o + n] for i, (o, n) in enumerate(recs) if i not in drop)


def read(path: Path) -> tuple[list, VelodynePcapReader]:
    reader = VelodynePcapReader(path)
    return list(reader), reader


def assert_same_frames(a: list, b: list) -> None:
    assert len(a) == len(b)
    for fa, fb in zip(a, b, strict=True):
        assert fa.stamp == fb.stamp
        np.testing.assert_array_equal(fa.points, fb.points)


@pytest.fixture(scope="module")
def clean():
    frames, reader = read(PCAP)
    return frames, reader.stats


def test_real_pcap_frames(clean):
    frames, stats = clean
    # README: two frames of 18,154 and 1,425 points, 32 rings.
    assert [len(f) for f in frames] == [18154, 1425]
    assert stats.damaged == 0 and stats.packets == 84 and stats.records == 100
    for f in frames:
        p = f.points
        assert p.dtype == POINT_DTYPE
        np.testing.assert_array_equal(np.unique(p["ring"]), np.arange(32))
        rng = np.sqrt(p["x"] ** 2 + p["y"] ** 2 + p["z"] ** 2)
        assert rng.min() > 0.1 and rng.max() < 130.0  # HDL-32E: up to ~100 m
        assert 0 <= p["intensity"].min() and p["intensity"].max() <= 255
        assert p["time"].min() > -0.11 and p["time"].max() < 0.01  # one 10 Hz rotation
    # host stamps from the capture (Nov 2014), in order, 9.3 ms apart
    assert 1415644617.0 < frames[0].stamp < frames[1].stamp < 1415644618.0
    # the points match velodyne-decoder's own pcap reader
    ref = list(vd.read_pcap(str(PCAP)))
    for f, (_, arr) in zip(frames, ref, strict=True):
        np.testing.assert_array_equal(f.points["x"], arr[:, 0])
        np.testing.assert_array_equal(f.points["ring"], arr[:, 6].astype(np.uint16))


def test_ring_elevations_are_hdl32e(clean):
    # HDL-32E lasers span -30.67..+10.67 degrees, ring 0 lowest.
    p = clean[0][0].points
    el = np.degrees(np.arctan2(p["z"], np.hypot(p["x"], p["y"])))
    per_ring = np.array([np.median(el[p["ring"] == r]) for r in range(32)])
    assert np.all(np.diff(per_ring) > 0)
    assert per_ring[0] == pytest.approx(-30.67, abs=0.3)
    assert per_ring[-1] == pytest.approx(10.67, abs=0.3)


@pytest.mark.parametrize("cut", [100, 1000, 60_000, 115_000])
def test_truncated_file_keeps_every_complete_packet(tmp_path, cut):
    data = PCAP.read_bytes()
    recs = records(data)
    complete = {i for i, (o, n) in enumerate(recs) if o + n <= cut}
    ref_path = tmp_path / "ref.pcap"
    ref_path.write_bytes(without(data, set(range(len(recs))) - complete))
    bad = tmp_path / "cut.pcap"
    bad.write_bytes(data[:cut])
    partial = any(o < cut < o + n for o, n in recs)
    if not complete:  # nothing but a broken first record: fail loudly
        with pytest.raises(ValueError, match="no usable"), pytest.warns(LidarDataWarning):
            read(bad)
        return
    ref_frames, _ = read(ref_path)
    with pytest.warns(LidarDataWarning, match="truncated"):
        frames, reader = read(bad)
    assert reader.stats.damaged == int(partial) == 1
    assert_same_frames(frames, ref_frames)


def test_corrupted_record_header_resynchronises(tmp_path):
    data = bytearray(PCAP.read_bytes())
    recs = records(bytes(data))
    hit = [20, 55]  # two data packets in the middle of the first rotation
    for i in hit:
        o, _ = recs[i]
        data[o + 8 : o + 16] = b"\xff" * 8  # caplen / origlen garbage
    bad = tmp_path / "bad.pcap"
    bad.write_bytes(bytes(data))
    ref = tmp_path / "ref.pcap"
    ref.write_bytes(without(PCAP.read_bytes(), set(hit)))
    with pytest.warns(LidarDataWarning, match="record header"):
        frames, reader = read(bad)
    assert reader.stats.reasons["record header"] == 2
    assert_same_frames(frames, read(ref)[0])
    assert [len(f) for f in frames] == [len(f) for f in read(ref)[0]]


@pytest.mark.parametrize(
    ("offset", "value", "reason"),
    [
        (42 + 0, b"\x00\x00", "block flag"),  # first block's 0xEEFF flag
        (42 + 500, b"\xff\xff", "block flag"),  # block 5 flag
        (42 + 102, b"\xff\xff", "azimuth"),  # block 1 azimuth = 65535
        (42 + 1205, b"\x22", "model id"),  # factory byte says VLP-16 mid-stream
        (42 + 1204, b"\x00", "factory bytes"),  # unknown return mode
        (14 + 10, b"\x00\x00", "IP checksum"),  # IP header checksum
    ],
)
def test_corrupted_packet_is_skipped_and_counted(tmp_path, offset, value, reason):
    data = bytearray(PCAP.read_bytes())
    recs = records(bytes(data))
    victim = 30
    o = recs[victim][0] + 16 + offset
    data[o : o + len(value)] = value
    bad = tmp_path / "bad.pcap"
    bad.write_bytes(bytes(data))
    ref = tmp_path / "ref.pcap"
    ref.write_bytes(without(PCAP.read_bytes(), {victim}))
    with pytest.warns(LidarDataWarning, match=reason):
        frames, reader = read(bad)
    assert reader.stats.damaged == 1 and reader.stats.reasons[reason] == 1
    assert_same_frames(frames, read(ref)[0])


def test_random_garbage_in_the_middle(tmp_path):
    data = bytearray(PCAP.read_bytes())
    rng = np.random.default_rng(3)
    start = len(data) // 2
    data[start : start + 3000] = rng.integers(0, 256, 3000, dtype=np.uint8).tobytes()
    bad = tmp_path / "bad.pcap"
    bad.write_bytes(bytes(data))
    recs = records(PCAP.read_bytes())
    touched = {i for i, (o, n) in enumerate(recs) if o < start + 3000 and o + n > start}
    ref = tmp_path / "ref.pcap"
    ref.write_bytes(without(PCAP.read_bytes(), touched))
    with pytest.warns(LidarDataWarning):
        frames, reader = read(bad)
    assert reader.stats.damaged >= 1
    # every record outside the damaged span comes through unchanged
    assert_same_frames(frames, read(ref)[0])


def test_not_a_pcap(tmp_path):
    bad = tmp_path / "x.pcap"
    bad.write_bytes(b"hello world" * 10)
    with pytest.raises(ValueError, match="not a libpcap"):
        read(bad)


def test_packet_validator_accepts_real_packets():
    packets = real_packets()
    assert len(packets) == 84
    for _, payload in packets:
        assert velodyne_packet_problem(payload, 0x21) is None


# ------------------------------------------------------------------------- ROS bags
def real_packets() -> list[tuple[float, bytes]]:
    out = []
    with PCAP.open("rb") as fh:
        for ts, buf in dpkt.pcap.Reader(fh):
            payload = bytes(dpkt.ethernet.Ethernet(buf).data.data.data)
            if len(payload) == 1206:
                out.append((ts, payload))
    return out


def scan_message(store, packets, stamp):
    scan_t = store.types["velodyne_msgs/msg/VelodyneScan"]
    pkt_t = store.types["velodyne_msgs/msg/VelodynePacket"]
    time_t = store.types["builtin_interfaces/msg/Time"]
    pkts = [
        pkt_t(
            stamp=time_t(sec=int(ts), nanosec=int((ts % 1) * 1e9)),
            data=np.frombuffer(data, dtype=np.uint8).copy(),
        )
        for ts, data in packets
    ]
    return scan_t(header=make_header(store, stamp, "velodyne"), packets=pkts)


def write_scan_bag(path: Path, scans: list, *, ros1: bool, garbage_after: int | None = None):
    from rosbags.rosbag1 import Writer as Writer1
    from rosbags.rosbag2 import Writer as Writer2

    store = lidar_typestore(ros1)
    msgtype = "velodyne_msgs/msg/VelodyneScan"
    ser = store.serialize_ros1 if ros1 else store.serialize_cdr
    writer = Writer1(path) if ros1 else Writer2(path, version=8)
    with writer:
        conn = writer.add_connection("/velodyne_packets", msgtype, typestore=store)
        for k, packets in enumerate(scans):
            stamp = packets[-1][0]
            writer.write(conn, int(stamp * 1e9), ser(scan_message(store, packets, stamp), msgtype))
            if garbage_after == k:
                writer.write(conn, int(stamp * 1e9) + 1, b"\x01\x02garbage")


@pytest.mark.parametrize("ros1", [False, True])
def test_velodyne_scan_bag(tmp_path, ros1):
    packets = real_packets()
    scans = [packets[:40], packets[40:]]
    # corrupt one packet's block flag inside the second scan
    bad = bytearray(packets[50][1])
    bad[100:102] = b"\x00\x00"
    scans[1] = [*packets[40:50], (packets[50][0], bytes(bad)), *packets[51:]]
    path = tmp_path / ("scans.bag" if ros1 else "scans")
    write_scan_bag(path, scans, ros1=ros1, garbage_after=0)
    reader = open_lidar(path)
    assert isinstance(reader, BagReader)
    with pytest.warns(LidarDataWarning):
        frames = list(reader)
    assert reader.stats.reasons == {"message": 1, "block flag": 1}
    assert len(frames) == 2
    # the decoded points equal velodyne-decoder's decode of the same (good) packets
    for f, pk in zip(frames, [packets[:40], packets[40:50] + packets[51:]], strict=True):
        ref_stamp, ref = vd.ScanDecoder(vd.Config()).decode(
            vd.PacketVector([vd.VelodynePacket(ts, d) for ts, d in pk])
        )
        np.testing.assert_array_equal(f.points["x"], ref[:, 0])
        np.testing.assert_array_equal(f.points["ring"], ref[:, 6])
        assert f.stamp == pytest.approx(ref_stamp.host, abs=1e-6)
        np.testing.assert_array_equal(np.unique(f.points["ring"]), np.arange(32))


@pytest.mark.parametrize("ros1", [False, True])
def test_pointcloud2_round_trip(tmp_path, ros1):
    from usvfast.lidar import VLP16Simulator, harbour_scene

    sim = VLP16Simulator(harbour_scene(seed=1, floats=5), seed=2)
    frames = [sim.scan((0.1 * i, 0.0, 0.0), 1_700_000_000.0 + 0.1 * i).frame for i in range(3)]
    path = write_pointcloud2_bag(tmp_path / ("pc.bag" if ros1 else "pc"), frames, ros1=ros1)
    back = list(open_lidar(path))
    assert len(back) == 3
    for a, b in zip(frames, back, strict=True):
        assert b.stamp == pytest.approx(a.stamp, abs=1e-9)
        np.testing.assert_array_equal(a.points, b.points)


def _cloud(stamp: float, columns: dict[str, np.ndarray], kinds: dict[str, int]):
    """A PointCloud2 (rosbags class) of the given fields, in their order, packed."""
    ts = lidar_typestore()
    dtype = np.dtype([(k, v.dtype) for k, v in columns.items()])
    packed = np.empty(len(next(iter(columns.values()))), dtype)
    for k, v in columns.items():
        packed[k] = v
    pf = ts.types["sensor_msgs/msg/PointField"]
    fields = [
        pf(name=k, offset=dtype.fields[k][1], datatype=kinds[k], count=1)  # type: ignore[index]
        for k in columns
    ]
    return ts.types["sensor_msgs/msg/PointCloud2"](
        header=make_header(ts, stamp, "lidar"), height=1, width=len(packed), fields=fields,
        is_bigendian=False, point_step=dtype.itemsize, row_step=dtype.itemsize * len(packed),
        data=packed.view(np.uint8).copy(), is_dense=True,
    )  # fmt: skip


def test_pointcloud2_point_times_of_other_drivers():
    """Per-point times: Ouster's `t` (uint32 ns after the stamp), Hesai's `timestamp`
    (float64 absolute s), Livox's `timestamp` (float64 absolute ns) and its `line` as ring."""
    stamp, n = 1_700_000_000.25, 5
    rel = np.linspace(0.0, 0.09, n)  # s after the stamp
    xyz = {k: np.arange(n, dtype=np.float32) + i for i, k in enumerate("xyz")}
    f32 = {"x": 7, "y": 7, "z": 7, "intensity": 7}
    ouster = _cloud(
        stamp,
        {**xyz, "t": np.round(rel * 1e9).astype(np.uint32), "ring": np.arange(n, dtype=np.uint16)},
        {**f32, "t": 6, "ring": 4},
    )
    hesai = _cloud(stamp, {**xyz, "timestamp": stamp + rel}, {**f32, "timestamp": 8})
    livox = _cloud(
        stamp,
        {
            **xyz,
            "tag": np.zeros(n, np.uint8),
            "line": np.array([0, 1, 2, 3, 0], np.uint8),
            "timestamp": (stamp + rel) * 1e9,
        },
        {**f32, "tag": 2, "line": 2, "timestamp": 8},
    )
    for msg, tol in ((ouster, 1e-9), (hesai, 1e-6), (livox, 1e-6)):
        got_stamp, pts = pointcloud2_to_points(msg)
        assert got_stamp == pytest.approx(stamp, abs=1e-9)
        np.testing.assert_allclose(pts["time"], rel, atol=tol)
        np.testing.assert_array_equal(pts["z"], xyz["z"])
    np.testing.assert_array_equal(pointcloud2_to_points(livox)[1]["ring"], [0, 1, 2, 3, 0])
    np.testing.assert_array_equal(pointcloud2_to_points(ouster)[1]["ring"], np.arange(n))


def test_bag_without_lidar_topic(tmp_path):
    from rosbags.rosbag2 import Writer

    store = lidar_typestore()
    path = tmp_path / "empty"
    with Writer(path, version=8) as w:
        w.add_connection("/chatter", "std_msgs/msg/String", typestore=store)
    with pytest.raises(ValueError, match="no VelodyneScan/PointCloud2"):
        list(open_lidar(path))


@pytest.mark.parametrize(
    ("magic", "endian", "scale"), [(0xA1B2C3D4, ">", 1), (0xA1B23C4D, "<", 1000)]
)
def test_other_pcap_byte_orders_and_nanoseconds(tmp_path, clean, magic, endian, scale):
    """The same capture rewritten big-endian or with nanosecond stamps reads the same."""
    data = PCAP.read_bytes()
    head = struct.unpack_from("<IHHiIII", data, 0)
    out = [struct.pack(endian + "IHHiIII", magic, *head[1:])]
    for o, n in records(data):
        sec, frac, incl, orig = struct.unpack_from("<IIII", data, o)
        out.append(struct.pack(endian + "IIII", sec, frac * scale, incl, orig))
        out.append(data[o + 16 : o + n])
    path = tmp_path / "other.pcap"
    path.write_bytes(b"".join(out))
    frames, reader = read(path)
    assert reader.stats.damaged == 0
    assert_same_frames(frames, clean[0])


@pytest.mark.parametrize("victim", [0, 1, 30, -2, -1])
def test_one_flipped_timestamp_byte_costs_one_record(tmp_path, victim):
    # ts_sec's second byte flipped: a jump of hours, plausible on its own. The neighbours agree
    # with each other, so this record is the damaged one; every later record is kept.
    data = bytearray(PCAP.read_bytes())
    recs = records(bytes(data))
    victim %= len(recs)
    data[recs[victim][0] + 1] ^= 0x40
    bad = tmp_path / "bad.pcap"
    bad.write_bytes(bytes(data))
    ref = tmp_path / "ref.pcap"
    ref.write_bytes(without(PCAP.read_bytes(), {victim}))
    with pytest.warns(LidarDataWarning, match="record timestamp"):
        frames, reader = read(bad)
    assert reader.stats.damaged == 1
    assert_same_frames(frames, read(ref)[0])


def test_clock_step_confirmed_by_the_next_records_is_kept(tmp_path, clean):
    # the capture host's clock steps 20 min forward mid-stream: a real jump, nothing damaged
    data = bytearray(PCAP.read_bytes())
    recs = records(bytes(data))
    for o, _ in recs[40:]:
        sec = struct.unpack_from("<I", data, o)[0]
        struct.pack_into("<I", data, o, sec + 1200)
    stepped = tmp_path / "step.pcap"
    stepped.write_bytes(bytes(data))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        frames, reader = read(stepped)
    assert reader.stats.damaged == 0
    assert sum(len(f) for f in frames) == sum(len(f) for f in clean[0])


def test_every_nth_rotation():
    """`every`: the bundled VelodyneScan bag read with every=4 gives rotations 0, 4, 8, ... of
    the full read, identical, with the others not deserialised; the pcap reader keeps every
    n-th decoded rotation; a bad `every` names the argument."""
    from importlib import resources

    bag = resources.files("usvfast") / "data" / "harbour" / "bag"
    full = []
    for k, frame in enumerate(BagReader(str(bag), topic="/velodyne_packets")):
        full.append(frame)
        if k == 20:
            break
    reader = BagReader(str(bag), topic="/velodyne_packets", every=4)
    some = []
    for frame in reader:
        some.append(frame)
        if len(some) == 6:
            break
    assert reader.stats.packets < 6 * 80 and reader.stats.records == 21
    for a, b in zip(full[::4], some, strict=True):
        assert a.stamp == b.stamp
        np.testing.assert_array_equal(a.points, b.points)
    frames, _ = read(PCAP)
    kept = list(VelodynePcapReader(PCAP, every=2))
    assert len(frames) == 2 and len(kept) == 1
    np.testing.assert_array_equal(kept[0].points, frames[0].points)
    for bad, err in ((0, ValueError), (True, TypeError), (1.5, TypeError)):
        with pytest.raises(err, match="every"):
            BagReader(str(bag), every=bad)
        with pytest.raises(err, match="every"):
            VelodynePcapReader(PCAP, every=bad)
