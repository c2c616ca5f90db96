"""NMEA reading speed: the u-blox ZED-F9P log replicated to 1,000,000 lines, read by
usvfast.nav.nmea.read_nmea and, as the baseline, by a bare pynmea2.parse loop over every line
(no times, no arrays), in one process.

    PYTHONPATH=python python benches/bench_nmea.py [--lines 1000000]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import pynmea2

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from usvfast.nav.nmea import read_nmea

from conftest import SHARED_DATA

LOG = SHARED_DATA / "nmea" / "ublox-zed-f9p-nmea.log"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--lines", type=int, default=1_000_000)
    args = parser.parse_args()
    body = [ln for ln in LOG.read_text().splitlines() if ln and not ln.startswith("#")]
    reps = -(-args.lines // len(body))
    lines = (body * reps)[: args.lines]
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "big.log"
        path.write_text("\n".join(lines) + "\n")
        t0 = time.perf_counter()
        log = read_nmea(path)
        t_ours = time.perf_counter() - t0
    t0 = time.perf_counter()
    parsed = 0
    for ln in lines:
        try:
            pynmea2.parse(ln, check=True)
            parsed += 1
        except pynmea2.ParseError:
            pass
    t_peer = time.perf_counter() - t0
    print(
        f"{len(lines):,} lines ({log.n_used:,} used, {log.n_ignored:,} ignored, "
        f"{log.n_damaged} damaged; {len(log.positions.time):,} distinct fix times)"
    )
    print(f"read_nmea          {t_ours:7.2f} s  {len(lines) / t_ours:12,.0f} sentences/s")
    print(
        f"pynmea2.parse loop {t_peer:7.2f} s  {len(lines) / t_peer:12,.0f} sentences/s "
        f"({parsed:,} parsed)"
    )
    print(f"ratio {t_peer / t_ours:.1f}x")


if __name__ == "__main__":
    main()
