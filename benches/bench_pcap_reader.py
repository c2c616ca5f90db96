"""Velodyne pcap reader: usvfast's record pass in Rust vs the same reader with its records
and frames read in Python and dpkt as before, and vs the velodyne-decoder path; same capture,
one process.

The capture is 30 s of a simulated VLP-16 at 10 Hz (`Vlp16Recorder`, buildings behind the
quays: about 10,000 points per rotation), written as a pcap (Ethernet / IPv4 / UDP, as a
laptop records it) to a temporary folder, or `--pcap FILE`. Timed over the whole capture (best
pass of `--repeat`), per rotation, for three readers (`tests/pcap_peer.py` holds the two old
ones):

- usvfast: `VelodynePcapReader`, the records and UDP payloads read by
  `_core.pcap_udp_datagrams` and the packets checked by `_core.velodyne_packet_check` (Rust),
  its own rotation cutter and decoder;
- dpkt records: `DpktPcapReader`, the same reader with the records walked in Python
  (`_iter_pcap_records`), the payloads taken out by dpkt and each packet checked by
  `velodyne_packet_problem`, as it was before;
- velodyne-decoder: `PeerPcapReader`, dpkt records, numpy packet checks, every packet
  through one velodyne-decoder `StreamDecoder`.

Rows: the whole reader (`list(reader)`); its first part, the records, their UDP payloads and
the packet checks (each reader's `_data_packets`); the rotations, the rest
(cutting, decoding, points as `POINT_DTYPE`, frames); the reader with `every=2` (the peer
decodes all rotations, the readers only the ones they yield).

The three give the same frames bit for bit (checked here). Prints the times per rotation and
the ratios of the old readers' times to usvfast's.

    python benches/bench_pcap_reader.py [--pcap FILE] [--seconds 30] [--repeat 5]
"""

from __future__ import annotations

import argparse
import mmap
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

from usvfast.lidar.packets import ReadStats
from usvfast.lidar.pcap import VelodynePcapReader

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from pcap_peer import DpktPcapReader, PeerPcapReader


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


def read_records(reader: VelodynePcapReader) -> int:
    """The first part of a reader: every record, its UDP payload and the packet checks (the
    reader's `_data_packets`); the number of data packets."""
    with reader.path.open("rb") as fh, mmap.mmap(fh.fileno(), 0, access=mmap.ACCESS_READ) as data:
        packets, count_to = reader._data_packets(data, ReadStats(), str(reader.path))
        n = sum(1 for _ in packets)
        count_to(None)
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
        readers = (VelodynePcapReader, DpktPcapReader, PeerPcapReader)
        for every in (1, 2):
            ours, *old = (list(cls(path, every=every)) for cls in readers)
            for ref in old:
                assert len(ours) == len(ref)
                for a, b in zip(ours, ref, strict=True):
                    assert a.stamp == b.stamp and a.points.tobytes() == b.points.tobytes()
        ours = list(VelodynePcapReader(path))
        r = args.repeat
        times = {}
        for cls in readers:
            times[cls, "reader"] = best(lambda cls=cls: list(cls(path)), r)
            times[cls, "every"] = best(lambda cls=cls: list(cls(path, every=2)), r)
            # the peer's records: DpktPcapReader's loop, its packets checked with numpy
            times[cls, "records"] = best(lambda cls=cls: read_records(cls(path)), r)
        packets = read_records(VelodynePcapReader(path))
        assert packets == read_records(DpktPcapReader(path))
    n = len(ours)
    points = sum(len(f) for f in ours) / n
    name = args.pcap or f"simulated {args.seconds:g} s VLP-16 capture"
    print(f"{name}: {n} rotations, {packets / n:.1f} packets, {points:.0f} points per rotation")
    print(
        "  per rotation, ms             usvfast   dpkt records   ratio   velodyne-decoder   ratio"
    )
    for label, key in [
        ("reader (list of frames)", "reader"),
        ("records, payloads, checks", "records"),
        ("rotations (the rest)", None),
        ("reader, every=2", "every"),
    ]:
        if key is None:
            t = [times[c, "reader"] - times[c, "records"] for c in readers]
        else:
            t = [times[c, key] for c in readers]
        a, b, c = (x / n * 1e3 for x in t)
        print(f"  {label:<25} {a:10.3f} {b:14.3f} {b / a:6.2f}x {c:18.3f} {c / a:6.2f}x")


if __name__ == "__main__":
    main()
