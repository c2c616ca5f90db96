"""Velodyne pcap reader: usvfast's rotation cutter and decoder vs the velodyne-decoder path,
same capture, one process.

The capture is 30 s of a simulated VLP-16 at 10 Hz (`Vlp16Recorder`, buildings behind the
quays: about 10,000 points per rotation), written as a pcap (Ethernet / IPv4 / UDP, as a
laptop records it) to a temporary folder, or `--pcap FILE`. Timed over the whole capture (best
pass of `--repeat`), per rotation:

- reader: `list(VelodynePcapReader(path))` against the reader as it was, with numpy checking
  the packets and every packet going through one velodyne-decoder `StreamDecoder`
  (`tests/pcap_peer.py`); both take the UDP payloads out with dpkt;
- records: the first part of each, reading the pcap records, their UDP payloads and checking
  each packet (`_iter_pcap_records`, dpkt, and each reader's own packet check);
- rotations: the rest (cutting, decoding, points as `POINT_DTYPE`, frames);
- reader with `every=2`: every other rotation (the peer decodes all of them, the reader
  only the ones it yields).

Both readers give the same frames bit for bit (checked here). Prints the times per rotation
and the ratios.

    python benches/bench_pcap_reader.py [--pcap FILE] [--seconds 30] [--repeat 5]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

from usvfast.lidar.packets import ReadStats, velodyne_packet_problem
from usvfast.lidar.pcap import VelodynePcapReader, _iter_pcap_records, _udp_payload

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from pcap_peer import PeerPcapReader, packet_problem


def simulate_pcap(folder: Path, seconds: float) -> Path:
    """`seconds` of simulated VLP-16 packets (buildings included) as `folder`/vlp16.pcap,
    stamped when a laptop would receive them."""
    from usvfast.sim.scene import make_world
    from usvfast.sim.velodyne import Vlp16Recorder, write_velodyne_pcap

    start = 1_686_909_600.0123
    recorder = Vlp16Recorder(make_world(1, seconds), start=start, seed=1, buildings=True)
    packets, times = [], []
    while (scan := recorder.next_scan()).stamp < start + seconds:
        packets.append(scan.packets)
        times.append(scan.packet_times + 24 * 55.296e-6 + 1e-4)
    path = folder / "vlp16.pcap"
    write_velodyne_pcap(path, np.concatenate(packets), np.concatenate(times))
    return path


def read_records(path: Path, udp_payload, packet_problem) -> int:
    """The first part of a reader: every record, its UDP payload (`udp_payload`) and the
    packet checks (`packet_problem`); the number of data packets."""
    data = path.read_bytes()
    stats, model_id, n = ReadStats(), None, 0
    for _, linktype, frame in _iter_pcap_records(data, stats, str(path)):
        udp = udp_payload(linktype, frame)
        if udp is not None and len(udp[1]) == 1206:
            if packet_problem(udp[1], model_id) is None:
                model_id = udp[1][1205]
                n += 1
    return n


def best(fn, repeat: int) -> float:
    """Best wall time of `repeat` calls of `fn`, s."""
    out = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        out = min(out, time.perf_counter() - t0)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--pcap", type=Path, help="a Velodyne capture (default: simulate one)")
    ap.add_argument("--seconds", type=float, default=30.0, help="simulated duration, s")
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    warnings.simplefilter("ignore")
    with tempfile.TemporaryDirectory() as tmp:
        path = args.pcap or simulate_pcap(Path(tmp), args.seconds)
        for every in (1, 2):
            ours = list(VelodynePcapReader(path, every=every))
            ref = list(PeerPcapReader(path, every=every))
            assert len(ours) == len(ref)
            for a, b in zip(ours, ref, strict=True):
                assert a.stamp == b.stamp and a.points.tobytes() == b.points.tobytes()
        ours = list(VelodynePcapReader(path))
        r = args.repeat
        t_ours = best(lambda: list(VelodynePcapReader(path)), r)
        t_peer = best(lambda: list(PeerPcapReader(path)), r)
        t_every = best(lambda: list(VelodynePcapReader(path, every=2)), r)
        t_peer_every = best(lambda: list(PeerPcapReader(path, every=2)), r)
        t_records = best(lambda: read_records(path, _udp_payload, velodyne_packet_problem), r)
        t_peer_records = best(lambda: read_records(path, _udp_payload, packet_problem), r)
        packets = read_records(path, _udp_payload, velodyne_packet_problem)
    n = len(ours)
    points = sum(len(f) for f in ours) / n
    name = args.pcap or f"simulated {args.seconds:g} s VLP-16 capture"
    print(f"{name}: {n} rotations, {packets / n:.1f} packets, {points:.0f} points per rotation")
    print("  per rotation                usvfast   velodyne-decoder   ratio")
    rows = [
        ("reader (list of frames)", t_ours, t_peer),
        ("records, payloads, checks", t_records, t_peer_records),
        ("rotations (the rest)", t_ours - t_records, t_peer - t_peer_records),
        ("reader, every=2", t_every, t_peer_every),
    ]
    for label, a, b in rows:
        print(f"  {label:<25} {a / n * 1e3:8.3f} ms   {b / n * 1e3:8.3f} ms   {b / a:6.2f}x")


if __name__ == "__main__":
    main()
