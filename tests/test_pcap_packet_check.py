"""The pcap reader's packet pass in Rust: `_core.velodyne_packet_check` against the reader's
old per-packet check (`velodyne_packet_problem`, chained on the model id of the last packet
that passed), and the whole reader against itself as it was (`pcap_peer.DpktPcapReader`:
records walked in Python, payloads taken out by dpkt, packets checked one by one) on the real
HDL-32E capture, damaged copies of it and simulated captures, frame for frame and count for
count, the counts compared after every frame too (what a caller that stops there sees)."""

from __future__ import annotations

import copy
import warnings

import numpy as np
import pytest
import velodyne_decoder as vd
from hypothesis import given, settings
from hypothesis import strategies as st
from pcap_peer import DpktPcapReader

from usvfast._core import pcap_udp_datagrams, velodyne_packet_check
from usvfast.lidar import LidarDataWarning
from usvfast.lidar.packets import VELODYNE_PACKET_SIZE, velodyne_packet_problem
from usvfast.lidar.pcap import VelodynePcapReader
from usvfast.sim.velodyne import write_velodyne_pcap

from conftest import SHARED_DATA

PCAP = SHARED_DATA / "lidar" / "velodyne_hdl32e.pcap"
#: Bytes of a packet the checks read: block flags and azimuths, return mode, model id.
HEADS = [*range(0, 1200, 100), *range(1, 1200, 100), *range(2, 1200, 100), *range(3, 1200, 100)]
FACTORY = [1204, 1205]


def chained(data: bytes, offsets: list[int]) -> tuple[list[bool], list[tuple[int, str]]]:
    """The reader's old loop: each packet through `velodyne_packet_problem` against the model
    id of the last one that passed; (passed, (index, problem) of the others)."""
    model_id, passed, problems = None, [], []
    for k, o in enumerate(offsets):
        payload = data[o : o + VELODYNE_PACKET_SIZE]
        problem = velodyne_packet_problem(payload, model_id)
        passed.append(problem is None)
        if problem is None:
            model_id = payload[1205]
        else:
            problems.append((k, problem))
    return passed, problems


@pytest.fixture(scope="module")
def real_packets() -> bytes:
    """The 84 data packets of the real capture, back to back."""
    data = PCAP.read_bytes()
    found = pcap_udp_datagrams(data)
    rows = zip(found["offsets"].tolist(), found["lengths"].tolist(), strict=True)
    return b"".join(data[o : o + n] for o, n in rows if n == 1206)


@settings(max_examples=300)
@given(
    picks=st.lists(st.integers(0, 83), min_size=0, max_size=40),
    edits=st.lists(
        st.tuples(
            st.integers(0, 39),
            st.sampled_from(HEADS + FACTORY) | st.integers(0, 1205),
            st.sampled_from([0x00, 0xFF, 0xEE, 0xDD, 0x8C, 0xA0, 0x21, 0x22, 0x24, 0x39])
            | st.integers(0, 255),
        ),
        max_size=8,
    ),
    shifts=st.lists(st.integers(-3000, 3000), max_size=3),
)
def test_check_against_the_old_loop(real_packets, picks, edits, shifts):
    """Real packets in any order (model switches: the real capture is HDL-32E, edits make
    VLP-16s, unknown models, broken flags and azimuths), some offsets moved off the packets
    or past the end."""
    packets = [bytearray(real_packets[k * 1206 : (k + 1) * 1206]) for k in picks]
    for k, at, value in edits:
        if k < len(packets):
            packets[k][at] = value
    data = b"".join(packets)
    offsets = [k * 1206 for k in range(len(packets))]
    for j, shift in enumerate(shifts):
        if offsets:
            offsets[j % len(offsets)] = max(0, offsets[j % len(offsets)] + shift)
    passed, problems = velodyne_packet_check(data, np.array(offsets, dtype=np.int64))
    ref_passed, ref_problems = chained(data, offsets)
    assert passed.dtype == np.bool_ and passed.tolist() == ref_passed
    assert problems == ref_problems


def test_check_arguments_are_named(real_packets):
    offsets = np.zeros(1, dtype=np.int64)
    for bad in (None, "x", np.zeros(4), np.zeros((2, 2), np.uint8)):
        with pytest.raises(TypeError, match=r"^data: expected bytes or a 1-D uint8 array"):
            velodyne_packet_check(bad, offsets)
    for bad in (None, [0], np.zeros(1), np.zeros((1, 1), np.int64), np.zeros(1, np.int32)):
        with pytest.raises(ValueError, match=r"^offsets: expected an int64 array of shape"):
            velodyne_packet_check(real_packets, bad)
    with pytest.raises(ValueError, match=r"^offsets: must be non-negative"):
        velodyne_packet_check(real_packets, np.array([0, -1]))
    with pytest.raises(ValueError, match=r"^offsets: must be a C-contiguous array"):
        velodyne_packet_check(real_packets, np.zeros(4, np.int64)[::2])
    passed, problems = velodyne_packet_check(real_packets, np.array([], dtype=np.int64))
    assert passed.shape == (0,) and problems == []


# --- the whole reader against itself as it was ---------------------------------------------


def read_both(path, **options) -> list:
    """(frames or (exception type, message), stats after each frame, final stats) of the
    reader and of its dpkt version."""
    out = []
    for cls in (VelodynePcapReader, DpktPcapReader):
        reader, frames, seen = cls(path, **options), [], []
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", LidarDataWarning)
            try:
                for frame in reader:
                    frames.append(frame)
                    seen.append(copy.deepcopy(reader.stats))  # what a caller stopping here sees
            except ValueError as exc:
                frames = (type(exc), str(exc))
        out.append((frames, seen, reader.stats))
    return out


def assert_same_reads(path, **options) -> list:
    """The same frames, and the same counts after every frame and at the end."""
    (ours, our_seen, our_stats), (ref, ref_seen, ref_stats) = read_both(path, **options)
    assert our_stats == ref_stats
    assert our_seen == ref_seen
    if isinstance(ref, tuple):
        assert ours == ref
        return []
    assert len(ours) == len(ref)
    for a, b in zip(ours, ref, strict=True):
        assert (a.stamp, a.index) == (b.stamp, b.index)
        assert a.points.tobytes() == b.points.tobytes()
    return ours


@pytest.mark.parametrize("data_port", [None, 2368, 8308, 2369])
def test_real_capture(data_port):
    """8308 holds the position packets: 512 bytes each, "packet length" damage there."""
    frames = assert_same_reads(PCAP, data_port=data_port)
    assert len(frames) == (2 if data_port in (None, 2368) else 0)


@settings(max_examples=60)
@given(
    edits=st.lists(
        st.tuples(st.integers(0, 99), st.sampled_from([0, 8, 9, 12, 16 + 12, 16 + 24, 16 + 38])),
        max_size=4,
    ),
    flips=st.lists(st.tuples(st.integers(0, 83), st.sampled_from(HEADS + FACTORY)), max_size=6),
    value=st.integers(0, 255),
    data_port=st.sampled_from([None, 2368, 8308]),
    model=st.sampled_from([None, vd.Model.HDL32E]),
    cut=st.none() | st.integers(24, 115_320),
)
def test_damaged_real_capture(tmp_path_factory, edits, flips, value, data_port, model, cut):
    """Record headers, Ethernet / IP / UDP header bytes and packet heads of the real capture
    edited, the end cut: the same frames, the same counts."""
    data = bytearray(PCAP.read_bytes())
    starts, pos = [], 24
    while pos < len(data):
        starts.append(pos)
        pos += 16 + int.from_bytes(data[pos + 8 : pos + 12], "little")
    for record, at in edits:
        data[starts[record] + at] = value
    packets = [s for s in starts if int.from_bytes(data[s + 8 : s + 12], "little") == 1248]
    for k, at in flips:
        data[packets[k % len(packets)] + 16 + 42 + at] ^= 0x5A
    path = tmp_path_factory.mktemp("damaged") / "d.pcap"
    path.write_bytes(bytes(data[:cut]))
    assert_same_reads(path, data_port=data_port, model=model)


def test_simulated_capture_with_a_model_switch(tmp_path):
    """A VLP-16 capture whose packets 150-159 claim to be HDL-32E and whose last 100 claim to
    be VLP-16 Hi-Res: all "model id" damage (the stream stays on its first model)."""
    rng = np.random.default_rng(3)
    k = 400
    raw = np.zeros((k, 1206), dtype=np.uint8)
    blocks = raw[:, :1200].reshape(k, 12, 100)
    blocks[:, :, 0], blocks[:, :, 1] = 0xFF, 0xEE
    azimuth = (np.arange(12 * k).reshape(k, 12) * 40) % 36000
    blocks[:, :, 2], blocks[:, :, 3] = azimuth & 0xFF, azimuth >> 8
    blocks[:, :, 4:] = rng.integers(0, 256, (k, 12, 96))
    raw[:, 1204], raw[:, 1205] = 0x37, 0x22
    raw[150:160, 1205] = 0x21
    raw[300:, 1205] = 0x24
    times = 1_686_909_600.0 + np.arange(k) * 1.327e-3
    path = tmp_path / "switch.pcap"
    write_velodyne_pcap(path, raw, times)
    frames = assert_same_reads(path)
    (_, _, stats), _ = read_both(path)
    assert stats.reasons["model id"] == 10 + 100 and stats.packets == 290
    assert len(frames) >= 3
