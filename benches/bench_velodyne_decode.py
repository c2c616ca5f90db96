"""Velodyne VelodyneScan decoding: usvfast's decoder vs velodyne-decoder, same messages, one
process.

The messages are the VelodyneScan rotations of a simulated VLP-16 bag, deserialised once by
rosbags before timing: by default the bundled harbour recording (30 s at 10 Hz, 300 rotations
of 75 packets, about 3,900 points each: no buildings), with `--simulate` a fresh 30 s VLP-16
bag of the same simulator with the buildings behind the quays (about 10,000 points per
rotation), written to a temporary folder. Two jobs, each timed over every rotation (best pass
of `--repeat`):

- decode: deserialised message -> (n, 8) float32 array and stamps. usvfast joins the payloads
  into one (k, 1206) array and calls `_core.decode_velodyne_scan`; velodyne-decoder's user
  builds a `VelodynePacket` per packet (host time from the packet stamp, payload bytes) and
  calls `ScanDecoder.decode` on a `PacketVector`, as `BagReader` did before.
- reader step: `BagReader._decode_scan` (packet checks, decode, points as `POINT_DTYPE`)
  against the same step with velodyne-decoder in place of the decoder (`tests/velodyne_peer.py`).

Both give the same bits (checked here on every rotation). Prints the time per rotation and
the ratio.

    python benches/bench_velodyne_decode.py [--bag DIR | --simulate] [--topic T] [--repeat 5]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from importlib import resources
from pathlib import Path

import numpy as np
import velodyne_decoder as vd

from usvfast._core import decode_velodyne_scan
from usvfast._time import ros_stamp_seconds
from usvfast.lidar.packets import (
    NATIVE_MODELS,
    ReadStats,
    VelodyneScanDecoder,
)
from usvfast.lidar.readers import BagReader, lidar_typestore

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from velodyne_peer import PeerBagReader


def simulate_bag(folder: Path, seconds: float = 30.0) -> Path:
    """A ROS 2 bag of `seconds` of simulated VLP-16 rotations (buildings included) in
    `folder`, topic /velodyne_packets."""
    from rosbags.rosbag2 import Writer

    from usvfast.lidar.readers import make_header
    from usvfast.sim.scene import make_world
    from usvfast.sim.velodyne import Vlp16Recorder

    start = 1_686_909_600.0123
    recorder = Vlp16Recorder(make_world(1, seconds), start=start, seed=1, buildings=True)
    store = lidar_typestore()
    msgtype = "velodyne_msgs/msg/VelodyneScan"
    scan_t, pkt_t = store.types[msgtype], store.types["velodyne_msgs/msg/VelodynePacket"]
    time_t = store.types["builtin_interfaces/msg/Time"]

    def stamp(t: float):
        sec = int(np.floor(t))
        return time_t(sec=sec, nanosec=min(round((t - sec) * 1e9), 999_999_999))

    path = folder / "bag"
    with Writer(path, version=8) as writer:
        conn = writer.add_connection("/velodyne_packets", msgtype, typestore=store)
        while (scan := recorder.next_scan()).stamp < start + seconds:
            packets = [
                pkt_t(stamp=stamp(float(t)), data=row.copy())
                for t, row in zip(scan.packet_times, scan.packets, strict=True)
            ]
            msg = scan_t(header=make_header(store, scan.stamp, "velodyne"), packets=packets)
            writer.write(conn, round(scan.stamp * 1e9), store.serialize_cdr(msg, msgtype))
    return path


def read_messages(bag: Path, topic: str) -> list:
    """Every VelodyneScan message of `topic`, deserialised."""
    from rosbags.highlevel import AnyReader

    with AnyReader([bag], default_typestore=lidar_typestore()) as reader:
        conns = [c for c in reader.connections if c.topic == topic]
        return [reader.deserialize(raw, c.msgtype) for c, _, raw in reader.messages(conns)]


def ours(msg, model: str):
    """usvfast: one contiguous payload array and one call."""
    raw = np.frombuffer(b"".join([p.data for p in msg.packets]), dtype=np.uint8)
    times = np.array([ros_stamp_seconds(p.stamp) for p in msg.packets])
    return decode_velodyne_scan(raw.reshape(len(msg.packets), 1206), times, model)


def peer(msg, decoder):
    """velodyne-decoder: a VelodynePacket per packet, a PacketVector, ScanDecoder.decode."""
    packets = vd.PacketVector(
        [vd.VelodynePacket(ros_stamp_seconds(p.stamp), bytes(p.data)) for p in msg.packets]
    )
    pair, arr = decoder.decode(packets)
    return (pair.host, pair.device), arr


def per_rotation(fn, messages: list, repeat: int) -> float:
    """Best time of `repeat` passes over `messages`, per message (s). Each result is dropped
    before the next message, as a reader's consumer does."""
    best = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        for m in messages:
            fn(m)
        best = min(best, time.perf_counter() - t0)
    return best / len(messages)


def assert_same(fn, ref, messages: list) -> None:
    """`fn` and `ref` give the same stamps and bytes on every message."""
    for m in messages:
        (s, a), (rs, b) = fn(m), ref(m)
        assert s == rs and a.tobytes() == b.tobytes()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    bundled = Path(str(resources.files("usvfast") / "data" / "harbour" / "bag"))
    ap.add_argument("--bag", type=Path, default=bundled, help="a bag of VelodyneScan messages")
    ap.add_argument("--simulate", action="store_true", help="a fresh 30 s VLP-16 bag")
    ap.add_argument("--topic", default="/velodyne_packets")
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    if args.simulate:
        with tempfile.TemporaryDirectory() as tmp:
            args.bag = simulate_bag(Path(tmp))
            messages = read_messages(args.bag, args.topic)
            args.bag = "simulated VLP-16 bag with buildings"
    else:
        messages = read_messages(args.bag, args.topic)
    model = NATIVE_MODELS[int(messages[0].packets[0].data[1205])]
    packets = sum(len(m.packets) for m in messages)
    r = args.repeat

    decoder = vd.ScanDecoder(vd.Config())
    decode_ours, decode_peer = (lambda m: ours(m, model)), (lambda m: peer(m, decoder))
    assert_same(decode_ours, decode_peer, messages)
    t_ours = per_rotation(decode_ours, messages, r)
    t_peer = per_rotation(decode_peer, messages, r)
    points = sum(decode_ours(m)[1].shape[0] for m in messages)

    reader, peer_reader = BagReader("unused"), PeerBagReader("unused")
    scan_decoder = VelodyneScanDecoder()
    stats = ReadStats()
    step_ours = lambda m: reader._decode_scan(m, scan_decoder, stats)  # noqa: E731
    step_peer = lambda m: peer_reader._decode_scan(m, None, stats)  # noqa: E731
    assert_same(step_ours, step_peer, messages)
    assert stats.damaged == 0
    t_step_ours = per_rotation(step_ours, messages, r)
    t_step_peer = per_rotation(step_peer, messages, r)

    n = len(messages)
    print(f"{args.bag}: {n} {model} rotations, {packets / n:.1f} packets, {points / n:.0f} points")
    print("  per rotation                     usvfast   velodyne-decoder   ratio")
    rows = [("decode (message -> (n, 8))", t_ours, t_peer)]
    rows.append(("reader step (_decode_scan)", t_step_ours, t_step_peer))
    for name, a, b in rows:
        print(f"  {name}   {a * 1e3:8.3f} ms   {b * 1e3:8.3f} ms   {b / a:6.1f}x")


if __name__ == "__main__":
    main()
