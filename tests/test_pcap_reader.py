"""The Velodyne pcap reader (its own rotation cutter and packet decoder) against its
velodyne-decoder path (every packet through one `StreamDecoder`), frame for frame and bit for
bit: the real HDL-32E capture with every option, truncated and byte-flipped copies of it,
simulated VLP-16 captures, and random packet streams with azimuth wraps anywhere, dual
returns, long gaps, other models and a model switch mid-stream."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest
import velodyne_decoder as vd
from hypothesis import given, settings
from hypothesis import strategies as st
from pcap_peer import PeerPcapReader, _iter_pcap_records
from pcap_peer import packet_problem as peer_packet_problem

from usvfast.lidar import LidarDataWarning
from usvfast.lidar.packets import (
    VELODYNE_PACKET_SIZE,
    ReadStats,
    packet_problems,
    velodyne_packet_problem,
)
from usvfast.lidar.pcap import RotationCutter, VelodynePcapReader
from usvfast.sim.scene import make_world
from usvfast.sim.velodyne import Vlp16Recorder, write_velodyne_pcap

from conftest import SHARED_DATA

PCAP = SHARED_DATA / "lidar" / "velodyne_hdl32e.pcap"
_CHANNEL = np.dtype([("distance", "<u2"), ("reflectivity", "u1")])
_BLOCK = np.dtype([("flag", "<u2"), ("azimuth", "<u2"), ("channels", _CHANNEL, (32,))])
PACKET = np.dtype(
    [("blocks", _BLOCK, (12,)), ("stamp", "<u4"), ("return_mode", "u1"), ("model", "u1")]
)


def read_both(path: Path, **kwargs) -> list:
    """(frames, stats) of the reader and of its velodyne-decoder twin; an exception of either
    is returned as (type, message) in place of the frames."""
    out = []
    for cls in (VelodynePcapReader, PeerPcapReader):
        reader = cls(path, **kwargs)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", LidarDataWarning)
            try:
                frames = list(reader)
            except Exception as exc:  # compared with the peer's
                frames = (type(exc), str(exc))
        out.append((frames, reader.stats))
    return out


def assert_same_reads(path: Path, **kwargs) -> list:
    """The reader's frames, stats and errors equal its velodyne-decoder path's; returns the
    frames ([] when both raised)."""
    (ours, our_stats), (ref, ref_stats) = read_both(path, **kwargs)
    assert our_stats == ref_stats
    if isinstance(ref, tuple):
        assert ours == ref
        return []
    assert len(ours) == len(ref)
    for a, b in zip(ours, ref, strict=True):
        assert (a.stamp, a.index, a.source) == (b.stamp, b.index, b.source)
        assert a.points.dtype == b.points.dtype
        assert a.points.tobytes() == b.points.tobytes()
    return ours


# --- the real HDL-32E capture ----------------------------------------------------------


@pytest.mark.parametrize(
    "options",
    [
        {},
        {"every": 2},
        {"every": 3},
        {"device_time": True},
        {"device_time": True, "every": 2},
        {"data_port": 2368},
        {"data_port": 2369},  # nothing on that port: both fail loudly
        {"model": vd.Model.HDL32E},
        {"model": vd.Model.VLP16},  # the decoder refuses every rotation
        {"model": vd.Model.PuckHiRes, "every": 2},
        {"model": vd.Model.VLP32C},  # velodyne-decoder's model, refused too
    ],
)
def test_real_capture(options):
    frames = assert_same_reads(PCAP, **options)
    if not options or options == {"data_port": 2368}:
        assert [len(f) for f in frames] == [18154, 1425]


def test_a_capture_of_another_model_is_damage_not_a_crash():
    """Every rotation refused by the configured model, the last one included: counted as
    "decoder" damage, then the reader's ValueError for a capture without a usable frame."""
    reader = VelodynePcapReader(PCAP, model=vd.Model.VLP16)
    with pytest.raises(ValueError, match="no usable LiDAR frame"), warnings.catch_warnings():
        warnings.simplefilter("ignore", LidarDataWarning)
        list(reader)
    assert reader.stats.reasons["decoder"] == 2 and reader.stats.frames == 0


@pytest.mark.parametrize("cut", [5_000, 60_000, 61_300, 100_000, 115_000])
def test_truncated_capture(tmp_path, cut):
    path = tmp_path / "cut.pcap"
    path.write_bytes(PCAP.read_bytes()[:cut])
    assert_same_reads(path)
    assert_same_reads(path, device_time=True)


@settings(max_examples=30)
@given(
    edits=st.lists(
        st.tuples(st.integers(24, 118_000), st.integers(0, 255)), min_size=1, max_size=6
    ),
    every=st.integers(1, 3),
)
def test_byte_flipped_capture(tmp_path_factory, edits, every):
    """Bytes set anywhere past the file header (record headers, Ethernet/IP/UDP headers,
    block flags, azimuths, factory bytes, distances)."""
    data = bytearray(PCAP.read_bytes())
    for at, value in edits:
        data[at % len(data)] = value
    path = tmp_path_factory.mktemp("flip") / "flip.pcap"
    path.write_bytes(bytes(data))
    assert_same_reads(path, every=every)


def test_azimuth_bytes_of_the_cut(tmp_path):
    """The last block's azimuth of every packet moved by half a turn, one packet at a time:
    the cut moves with it (or the packet is refused as damaged)."""
    data = PCAP.read_bytes()
    seen = set()
    for k, (_, _, frame) in enumerate(_iter_pcap_records(data, ReadStats(), "x")):
        if len(frame) != 42 + VELODYNE_PACKET_SIZE or k % 7:
            continue
        at = data.index(frame) + 42 + 1102
        bad = bytearray(data)
        azimuth = (bad[at] | bad[at + 1] << 8) + 18000
        bad[at : at + 2] = (azimuth % 36000).to_bytes(2, "little")
        path = tmp_path / f"az{k}.pcap"
        path.write_bytes(bytes(bad))
        seen.add(len(assert_same_reads(path)))
    assert len(seen) > 1  # some edits changed the number of rotations


# --- simulated VLP-16 captures ---------------------------------------------------------


@pytest.fixture(scope="module")
def vlp16_pcap(tmp_path_factory) -> Path:
    """2 s of a simulated VLP-16 (buildings included) as a capture."""
    start = 1_686_909_600.0123
    rec = Vlp16Recorder(make_world(2, 2.0), start=start, seed=2, buildings=True)
    scans = [rec.next_scan() for _ in range(20)]
    path = tmp_path_factory.mktemp("vlp16") / "vlp16.pcap"
    packets = np.concatenate([s.packets for s in scans])
    times = np.concatenate([s.packet_times for s in scans]) + 24 * 55.296e-6 + 1e-4
    write_velodyne_pcap(path, packets, times)
    return path


@pytest.mark.parametrize(
    "options",
    [{}, {"every": 3}, {"device_time": True}, {"model": vd.Model.VLP16, "data_port": 2368}],
)
def test_simulated_vlp16_capture(vlp16_pcap, options):
    frames = assert_same_reads(vlp16_pcap, **options)
    assert len(frames) >= 19 // options.get("every", 1)
    assert all(len(f) > 5000 for f in frames[1:-1])


# --- random packet streams -------------------------------------------------------------

MODEL_IDS = [0x22, 0x24, 0x21, 0x28]  # VLP-16, VLP-16 Hi-Res, HDL-32E; VLP-32C by velodyne-decoder


@st.composite
def streams(draw) -> tuple[np.ndarray, np.ndarray]:
    """(payloads (k, 1206), host times (k,)) of a random capture: runs of packets of a model
    and return mode spinning at some rate from some azimuth (wraps through 0 anywhere, now
    and then backwards or a jump), host times with jitter, reordering and gaps past the
    cutter's 0.3 s."""
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    runs = draw(st.integers(1, 4))
    chunks, times = [], []
    t = draw(st.sampled_from([1_686_909_600.0, 1_686_911_399.95, 1_415_644_617.2]))
    azimuth = draw(st.integers(0, 35999))
    model = draw(st.sampled_from(MODEL_IDS))
    for _ in range(runs):
        if draw(st.booleans()):  # a model switch mid-stream (another model or the same)
            model = draw(st.sampled_from(MODEL_IDS))
        k = draw(st.integers(1, 90))
        mode = draw(st.sampled_from([0x37, 0x38, 0x39]))
        step = draw(st.sampled_from([0, 1, 17, 40, 200, 1500, 3000, 18000, 35990, 36001]))
        raw = np.zeros(k, dtype=PACKET)
        blocks = raw["blocks"]
        blocks["flag"] = 0xEEFF
        spin = azimuth + step * np.arange(12 * k).reshape(k, 12) // 12
        spin += rng.integers(0, 3, (k, 12)) * (rng.random((k, 1)) < 0.1)
        blocks["azimuth"] = spin % 36000
        azimuth = int(spin[-1, -1] + step) % 36000
        counts = rng.integers(0, 60_000, (k, 12, 32))
        counts[rng.random(counts.shape) < 0.3] = 0
        if mode == 0x39:
            same = rng.random((k, 6, 32)) < 0.4
            counts[:, 1::2] = np.where(same, counts[:, 0::2], counts[:, 1::2])
        blocks["channels"]["distance"] = counts
        blocks["channels"]["reflectivity"] = rng.integers(0, 256, (k, 12, 32))
        dt = draw(st.sampled_from([1.327e-3, 2.7e-3, 0.01, 0.11]))
        run_times = t + dt * np.arange(k) + rng.normal(0.0, 2e-4, k)
        gaps = rng.random(k) < 0.03
        run_times += np.cumsum(gaps * rng.uniform(0.25, 0.6, k))
        t = float(run_times[-1]) + dt
        raw["stamp"] = np.round(run_times % 3600 * 1e6).astype(np.int64) % 3_600_000_000
        raw["return_mode"] = mode
        raw["model"] = model
        chunks.append(raw.view(np.uint8).reshape(k, 1206))
        times.append(run_times)
    payloads = np.concatenate(chunks)
    assert packet_problems([bytes(p) for p in payloads]) == [None] * len(payloads)
    return payloads, np.concatenate(times)


@pytest.mark.parametrize("model", [None, vd.Model.VLP16, vd.Model.HDL32E, vd.Model.VLP32C])
@given(data=st.data())
def test_random_streams(tmp_path_factory, model, data):
    payloads, times = data.draw(streams())
    path = tmp_path_factory.mktemp("stream") / "s.pcap"
    write_velodyne_pcap(path, payloads, times)
    every = data.draw(st.integers(1, 3))
    assert_same_reads(path, model=model, every=every, device_time=data.draw(st.booleans()))


# --- the cutter on its own -------------------------------------------------------------


def test_cutter_cuts_after_the_wrap_and_before_a_gap():
    def packet(azimuth: int) -> bytes:
        raw = bytearray(VELODYNE_PACKET_SIZE)
        raw[1102:1104] = azimuth.to_bytes(2, "little")
        return bytes(raw)

    cutter = RotationCutter()
    azimuths = [100, 9000, 18000, 18200, 27000, 35000, 150, 9000, 20000, 30000]
    times = [0.0, 0.02, 0.04, 0.06, 0.08, 0.1, 0.12, 0.14, 0.16, 0.5]
    cuts = [cutter.push(packet(a), t) for a, t in zip(azimuths, times, strict=True)]
    done = [(k, c[1]) for k, c in enumerate(cuts) if c is not None]
    # passing the start azimuth (35000 -> 150, past 100) ends the first rotation with the
    # packet at 150; the 0.34 s gap
    # ends the second before the packet at 30000, which starts the third
    assert done == [(6, times[:7]), (9, times[7:9])]
    rest = cutter.finish()
    assert rest is not None and rest[1] == [0.5]
    assert cutter.finish() is None


# --- the packet checks against numpy --------------------------------


@pytest.fixture(scope="module")
def real_frames() -> list[tuple[int, bytes]]:
    data = PCAP.read_bytes()
    return [(link, frame) for _, link, frame in _iter_pcap_records(data, ReadStats(), "x")]


@settings(max_examples=300)
@given(
    packet=st.integers(0, 83),
    edits=st.lists(st.tuples(st.integers(0, 1205), st.integers(0, 255)), max_size=4),
    model_id=st.sampled_from([None, 0x21, 0x22]),
)
def test_packet_problem_as_numpy_checks(real_frames, packet, edits, model_id):
    payloads = [f[42:] for _, f in real_frames if len(f) == 42 + VELODYNE_PACKET_SIZE]
    raw = bytearray(payloads[packet])
    for at, value in edits:
        raw[at] = value
    head = [*range(0, 1200, 100), *range(1, 1200, 100)]
    if edits and edits[0][1] < 128:  # flags and azimuths of another kind
        raw[head[edits[0][1] % 24]] = 0xDD if edits[0][1] % 2 else 0x8C
    assert velodyne_packet_problem(bytes(raw), model_id) == peer_packet_problem(
        bytes(raw), model_id
    )


def test_simulated_capture_writer_checks_shapes(tmp_path):
    packets, times = np.zeros((3, 1206), dtype=np.uint8), np.zeros(3)
    for bad in ((packets[:, :1205], times), (packets, times[:2]), (packets[0], times[:1])):
        with pytest.raises(ValueError, match="packets, packet_times: expected"):
            write_velodyne_pcap(tmp_path / "x.pcap", *bad)
