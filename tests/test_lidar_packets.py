"""The vectorised packet check of the VelodyneScan decoder equals the one-packet check
(`velodyne_packet_problem`, the reference) on simulated VLP-16 packets with random damage."""

from __future__ import annotations

import numpy as np

from usvfast.lidar.packets import packet_problems, velodyne_packet_problem
from usvfast.sim.scene import make_world
from usvfast.sim.velodyne import Vlp16Recorder


def test_vectorised_packet_check_equals_the_reference():
    world = make_world(3, 5.0)
    rec = Vlp16Recorder(world, start=1_686_909_600.0, seed=3, buildings=False)
    good = [bytes(p) for p in rec.next_scan().packets]
    assert len(good) > 30
    rng = np.random.default_rng(0)
    payloads = []
    for p in good * 8:
        b = bytearray(p)
        kind = rng.integers(0, 6)
        if kind == 1:  # a block flag
            k = 100 * int(rng.integers(0, 12))
            b[k : k + 2] = bytes(rng.integers(0, 256, 2, dtype=np.uint8))
        elif kind == 2:  # an azimuth
            k = 100 * int(rng.integers(0, 12)) + 2
            b[k : k + 2] = int(rng.integers(35990, 65536)).to_bytes(2, "little")
        elif kind == 3:  # factory bytes
            b[1204 + int(rng.integers(0, 2))] = int(rng.integers(0, 256))
        elif kind == 4:  # length
            b = b[: int(rng.integers(0, 1300))] if rng.random() < 0.5 else b + b"\0"
        payloads.append(bytes(b))
    expected = [velodyne_packet_problem(p) for p in payloads]
    assert packet_problems(payloads) == expected
    assert set(expected) >= {None, "block flag", "azimuth", "factory bytes", "packet length"}
    assert packet_problems([]) == []
