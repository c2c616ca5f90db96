"""usvfast's Velodyne packet decoder (`_core.decode_velodyne_scan`) against velodyne-decoder's
`ScanDecoder`, bit for bit: the real HDL-32E capture, simulated VLP-16 rotations, random valid
packets of every model and return mode, and the full azimuth table; its argument errors; and
the bag reader, whose frames, stamps and damage counts equal those of its velodyne-decoder
path."""

from __future__ import annotations

import warnings
from pathlib import Path

import dpkt
import numpy as np
import pytest
import velodyne_decoder as vd
from hypothesis import given
from hypothesis import strategies as st
from velodyne_peer import PeerBagReader

from usvfast import DimensionError, NonFiniteError
from usvfast._core import decode_velodyne_scan
from usvfast.lidar import BagReader, LidarDataWarning
from usvfast.lidar.packets import packet_problems
from usvfast.lidar.readers import lidar_typestore, make_header
from usvfast.sim.scene import make_world
from usvfast.sim.velodyne import Vlp16Recorder

from conftest import SHARED_DATA

PCAP = SHARED_DATA / "lidar" / "velodyne_hdl32e.pcap"
MODELS = {"HDL-32E": 0x21, "VLP-16": 0x22, "VLP-16 Hi-Res": 0x24}
_CHANNEL = np.dtype([("distance", "<u2"), ("reflectivity", "u1")])
_BLOCK = np.dtype([("flag", "<u2"), ("azimuth", "<u2"), ("channels", _CHANNEL, (32,))])
PACKET = np.dtype(
    [("blocks", _BLOCK, (12,)), ("stamp", "<u4"), ("return_mode", "u1"), ("model", "u1")]
)


def peer(payloads: np.ndarray, times: np.ndarray):
    """velodyne-decoder's ((host, device), (n, 8)) of one rotation, a fresh decoder."""
    packets = [vd.VelodynePacket(float(t), bytes(p)) for t, p in zip(times, payloads, strict=True)]
    stamp, arr = vd.ScanDecoder(vd.Config()).decode(vd.PacketVector(packets))
    return (stamp.host, stamp.device), arr


def assert_bit_identical(payloads: np.ndarray, times: np.ndarray, model: str) -> np.ndarray:
    stamps, ours = decode_velodyne_scan(payloads, times, model)
    ref_stamps, ref = peer(payloads, times)
    assert stamps == ref_stamps
    assert ours.dtype == np.float32 and ours.shape == ref.shape
    assert ours.flags.c_contiguous
    assert ours.tobytes() == ref.tobytes()  # every bit, NaN and signed zeros alike
    return ours


# --- (a) the real HDL-32E capture -------------------------------------------------------


@pytest.fixture(scope="module")
def real():
    payloads, times = [], []
    with PCAP.open("rb") as fh:
        for ts, buf in dpkt.pcap.Reader(fh):
            payload = bytes(dpkt.ethernet.Ethernet(buf).data.data.data)
            if len(payload) == 1206:
                payloads.append(np.frombuffer(payload, dtype=np.uint8))
                times.append(ts)
    return np.stack(payloads), np.array(times)


@pytest.mark.parametrize("window", [(0, 84), (0, 40), (40, 84), (7, 8), (30, 71)])
def test_real_hdl32e_capture(real, window):
    payloads, times = real
    a, b = window
    out = assert_bit_identical(payloads[a:b], times[a:b], "HDL-32E")
    assert out.shape[0] > 100 * (b - a)
    if b - a > 10:
        np.testing.assert_array_equal(np.unique(out[:, 6]), np.arange(32))


# --- (b) simulated VLP-16 rotations ----------------------------------------------------


@pytest.fixture(scope="module")
def sim_scans():
    rec = Vlp16Recorder(make_world(5, 5.0), start=1_686_909_600.0123, seed=5, buildings=False)
    return [rec.next_scan() for _ in range(3)]


def test_simulated_vlp16_rotations(sim_scans):
    for scan in sim_scans:
        out = assert_bit_identical(scan.packets, scan.packet_times, "VLP-16")
        assert out.shape[0] == scan.points.shape[0] > 1000


# --- (c) random valid packets ----------------------------------------------------------


@st.composite
def rotations(draw, model: str, mode: int):
    """(payloads (k, 1206), host times (k,), model) of random but structurally valid packets
    of `model` in return `mode`: distances anywhere in 0..65535 with zeros and counts around
    the 0.1 m minimum range; azimuths of a steady spin through the 35999 -> 0 wrap or at
    random; device stamps anywhere in the hour; host times before the epoch, around it and
    in any hour; an 0xDDFF block now and then (the decoder stops reading the packet there)."""
    k = draw(st.integers(1, 8))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    raw = np.zeros(k, dtype=PACKET)
    blocks = raw["blocks"]
    blocks["flag"] = 0xEEFF
    if draw(st.booleans()):  # a steady spin: 0.01° per block, wrapping at 36000
        start = draw(st.integers(35000, 35999) | st.integers(0, 35999))
        step = draw(st.integers(0, 90))
        spin = start + step * np.arange(12 * k).reshape(k, 12)
        blocks["azimuth"] = spin % 36000
    else:
        blocks["azimuth"] = rng.integers(0, 36000, (k, 12))
    counts = rng.integers(0, 65536, (k, 12, 32))
    zeros = rng.random(counts.shape) < draw(st.floats(0.0, 1.0))
    near = rng.random(counts.shape) < 0.2
    counts[near] = rng.integers(45, 56, int(near.sum()))  # 0.1 m = 50 counts
    counts[zeros] = 0
    if mode == 0x39:  # dual: some strongest returns equal to the last ones
        same = rng.random((k, 6, 32)) < 0.4
        counts[:, 1::2] = np.where(same, counts[:, 0::2], counts[:, 1::2])
    blocks["channels"]["distance"] = counts
    blocks["channels"]["reflectivity"] = rng.integers(0, 256, (k, 12, 32))
    if draw(st.booleans()):
        blocks["flag"][rng.integers(0, k), rng.integers(0, 12)] = 0xDDFF
    if draw(st.booleans()):
        raw["stamp"] = rng.integers(0, 3_600_000_000, k)
    else:
        raw["stamp"] = (rng.integers(0, 3_600_000_000) + 1327 * np.arange(k)) % 3_600_000_000
    raw["return_mode"] = mode
    raw["model"] = MODELS[model]
    host0 = draw(
        st.sampled_from([0.0, 1_686_909_600.0, 1_686_911_399.9, 4_294_967_295.5])
        | st.floats(-1e6, 5e9)
    )
    times = host0 + np.sort(rng.random(k)) * draw(st.sampled_from([0.0, 1e-3, 0.1, 4000.0]))
    payloads = raw.view(np.uint8).reshape(k, 1206)
    assert packet_problems([bytes(p) for p in payloads]) == [None] * k
    return payloads, times, model


@pytest.mark.parametrize("mode", [0x37, 0x38, 0x39])
@pytest.mark.parametrize("model", sorted(MODELS))
@given(data=st.data())
def test_random_packets(model, mode, data):
    assert_bit_identical(*data.draw(rotations(model, mode)))


@pytest.mark.parametrize("model", sorted(MODELS))
@pytest.mark.parametrize("mode", [0x37, 0x38, 0x39])
def test_every_azimuth_and_laser(model, mode):
    """Each of the 36000 azimuth counts, at a standstill (no interpolation), on every laser."""
    raw = np.zeros(3000, dtype=PACKET)
    raw["blocks"]["flag"] = 0xEEFF
    raw["blocks"]["azimuth"] = np.arange(36000).reshape(3000, 12)
    raw["blocks"]["azimuth"][:, 11] = raw["blocks"]["azimuth"][:, 0]
    raw["blocks"]["channels"]["distance"] = 5000 + 997 * np.arange(32)
    raw["blocks"]["channels"]["reflectivity"] = np.arange(32)
    raw["stamp"] = 1_000_000 + 1327 * np.arange(3000)
    raw["return_mode"], raw["model"] = mode, MODELS[model]
    times = 1_686_909_600.0 + 1.327e-3 * np.arange(3000)
    assert_bit_identical(raw.view(np.uint8).reshape(3000, 1206), times, model)


# --- argument errors -------------------------------------------------------------------


def test_bad_arguments_name_the_argument(sim_scans):
    p, t = sim_scans[0].packets[:3], sim_scans[0].packet_times[:3]
    decode_velodyne_scan(p, t, "VLP-16")  # the good call
    cases = [
        ((p.astype(np.int16), t, "VLP-16"), ValueError, "payloads: expected a uint8 array"),
        ((p.tolist(), t, "VLP-16"), ValueError, "payloads: expected a uint8 array.*list"),
        ((p.reshape(-1), t, "VLP-16"), ValueError, "payloads: expected a uint8 array"),
        ((p[:, :1205].copy(), t, "VLP-16"), DimensionError, r"payloads: expected shape \(k, 1206"),
        ((p, t[:2], "VLP-16"), DimensionError, "payloads: .*len\\(packet_times\\) = 2"),
        ((p[:0], t[:0], "VLP-16"), DimensionError, "payloads"),
        ((p, t.astype(np.float32), "VLP-16"), ValueError, "packet_times: expected a float64"),
        ((p, t[:, None], "VLP-16"), ValueError, "packet_times: expected a float64"),
        ((p, np.r_[t[:2], np.nan], "VLP-16"), NonFiniteError, "packet_times"),
        ((p[:, ::-1], t, "VLP-16"), ValueError, "payloads: must be a C-contiguous array"),
        ((p, t[::-1][::-1].repeat(2)[::2], "VLP-16"), ValueError, "packet_times: must be a C-"),
        ((p, t, "VLP-32C"), ValueError, "model: expected one of"),
        ((p, t, "HDL-32E"), ValueError, "payloads: packet 0 has model id 0x22, expected 0x21"),
    ]  # fmt: skip
    for args, error, message in cases:
        with pytest.raises(error, match=message):
            decode_velodyne_scan(*args)
    bad = p.copy()
    bad[2, 1204] = 0x30
    with pytest.raises(ValueError, match="payloads: packet 2 has return mode 0x30"):
        decode_velodyne_scan(bad, t, "VLP-16")
    bad = p.copy()
    bad[1, 1205] = 0x24
    with pytest.raises(ValueError, match="payloads: packet 1 has model id 0x24"):
        decode_velodyne_scan(bad, t, "VLP-16")


# --- the bag reader --------------------------------------------------------------------


def read_both(path: Path, **kwargs):
    """(frames, stats) of the reader and of its velodyne-decoder twin; a `ValueError` of
    either (nothing usable) is returned in place of the frames."""
    out = []
    for cls in (BagReader, PeerBagReader):
        reader = cls(path, **kwargs)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", LidarDataWarning)
            try:
                frames = list(reader)
            except ValueError as exc:
                frames = str(exc)
        out.append((frames, reader.stats))
    return out


def assert_same_reads(path: Path, **kwargs) -> list:
    (ours, our_stats), (ref, ref_stats) = read_both(path, **kwargs)
    assert our_stats == ref_stats
    if isinstance(ref, str):
        assert ours == ref
        return []
    assert len(ours) == len(ref)
    for a, b in zip(ours, ref, strict=True):
        assert (a.stamp, a.index, a.source) == (b.stamp, b.index, b.source)
        assert a.points.tobytes() == b.points.tobytes()
    return ours


def test_bundled_bag_equals_the_velodyne_decoder_path():
    from importlib import resources

    bag = Path(str(resources.files("usvfast") / "data" / "harbour" / "bag"))
    frames = assert_same_reads(bag, topic="/velodyne_packets")
    assert len(frames) == 300
    assert len(assert_same_reads(bag, topic="/velodyne_packets", device_time=True)) == 300


def write_scans(path: Path, scans: list[tuple[np.ndarray, np.ndarray]]) -> Path:
    """A ROS 2 bag of VelodyneScan messages, one per (payloads, packet times)."""
    from rosbags.rosbag2 import Writer

    store = lidar_typestore()
    msgtype = "velodyne_msgs/msg/VelodyneScan"
    scan_t, pkt_t = store.types[msgtype], store.types["velodyne_msgs/msg/VelodynePacket"]
    time_t = store.types["builtin_interfaces/msg/Time"]
    with Writer(path, version=8) as writer:
        conn = writer.add_connection("/velodyne_packets", msgtype, typestore=store)
        for k, (payloads, times) in enumerate(scans):
            packets = [
                pkt_t(stamp=time_t(sec=int(t), nanosec=int(t % 1 * 1e9)), data=p.copy())
                for p, t in zip(payloads, times, strict=True)
            ]
            msg = scan_t(header=make_header(store, float(times[-1]), "velodyne"), packets=packets)
            writer.write(conn, 1_000_000_000 * (k + 1), store.serialize_cdr(msg, msgtype))
    return path


def test_reader_on_mixed_and_damaged_rotations(tmp_path, real, sim_scans):
    """Rotations of several models in one bag, damaged packets, a foreign block: the reader's
    frames and damage counts equal the velodyne-decoder path's, however the model is set."""
    hdl = (real[0][:40], real[1][:40])
    vlp = [(s.packets, s.packet_times) for s in sim_scans]
    dual = vlp[1][0].copy()
    dual[:, 1204] = 0x39
    hires = vlp[2][0].copy()
    hires[:, 1205] = 0x24
    vlp32 = vlp[0][0].copy()
    vlp32[:, 1205] = 0x28  # decoded by velodyne-decoder as a VLP-32C
    damaged = vlp[2][0].copy()
    damaged[3, 0:2] = 0  # block flag: skipped by the reader
    damaged[5, 100:102] = (0xFF, 0xDD)  # a lower-bank flag: the decoder stops at that block
    damaged[9, 1205] = 0x21  # another model inside a rotation
    rotations = {
        "vlp16": vlp[0],
        "hdl32e": hdl,
        "dual": (dual, vlp[1][1]),
        "hires": (hires, vlp[2][1]),
        "vlp32c": (vlp32, vlp[0][1]),
        "damaged": (damaged, vlp[2][1]),
    }
    orders = [
        ["vlp16", "hdl32e", "dual", "damaged", "hires", "vlp32c"],
        ["hdl32e", "vlp16", "hdl32e"],
        ["vlp32c", "vlp16", "vlp32c"],
        ["hires", "vlp16", "damaged"],
    ]
    models = [None, vd.Model.VLP16, vd.Model.PuckLite, vd.Model.PuckHiRes, vd.Model.HDL32E]
    models += [vd.Model.VLP32C]
    decoded = 0
    for i, order in enumerate(orders):
        path = write_scans(tmp_path / f"bag{i}", [rotations[name] for name in order])
        for model in models:
            frames = assert_same_reads(path, model=model)
            decoded += len(frames)
    assert decoded > 20


def test_every_lidar_stream_model_name_is_a_velodyne_decoder_model():
    """The `lidar` stream's `model` option: every name resolves to velodyne-decoder's Model;
    an unknown one is a ValueError naming the option."""
    from usvfast.pipeline.streams import _MODELS, _model

    for name in _MODELS:
        assert isinstance(_model(name), vd.Model), name
    with pytest.raises(ValueError, match="model: expected one of"):
        _model("HDL-64E")
