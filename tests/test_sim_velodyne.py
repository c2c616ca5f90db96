"""Simulated VLP-16 packets against the real decoder (velodyne-decoder): the decoded points
are the simulated ones within 2 mm and 0.01°, with their rings, intensities and times."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
import velodyne_decoder as vd

from usvfast.frames import rotation_matrix
from usvfast.lidar.packets import velodyne_packet_problem
from usvfast.sim.scene import make_world
from usvfast.sim.velodyne import PACKET_DTYPE, PACKET_SIZE, Vlp16Recorder, decoded_azimuths

START = 1_686_909_600.0 + 0.0123


@pytest.fixture(scope="module")
def scans():
    world = make_world(5, 5.0)
    rec = Vlp16Recorder(world, start=START, seed=5, buildings=False)
    return [rec.next_scan() for _ in range(3)]


def _decode(scan):
    pairs = zip(scan.packet_times, scan.packets, strict=True)
    packets = [vd.VelodynePacket(float(t), bytes(p)) for t, p in pairs]
    return vd.ScanDecoder(vd.Config()).decode(vd.PacketVector(packets))


def test_packet_layout(scans):
    assert PACKET_DTYPE.itemsize == PACKET_SIZE == 1206
    scan = scans[1]
    raw = scan.packets.view(PACKET_DTYPE).reshape(-1)
    assert (raw["blocks"]["flag"] == 0xEEFF).all()
    assert (raw["return_mode"] == 0x37).all() and (raw["product"] == 0x22).all()
    assert (raw["blocks"]["azimuth"] < 36000).all()
    # timestamp: microseconds past the hour of each packet's first firing
    expected = np.round((scan.packet_times % 3600.0) * 1e6)
    assert np.array_equal(raw["timestamp"].astype(np.int64), expected.astype(np.int64))
    # 24 firings of 55.296 us per packet; about 75 packets per rotation at 600 rpm
    assert np.allclose(np.diff(scan.packet_times), 24 * 55.296e-6, rtol=0, atol=1e-6)
    assert 74 <= len(scan.packets) <= 77
    assert all(velodyne_packet_problem(bytes(p)) is None for p in scan.packets)
    # the scan is cut where the azimuth wraps: first blocks run from just after 0 deg on
    first = raw["blocks"]["azimuth"][:, 0]
    assert first[0] < 500 and first[-1] > 35000 and (np.diff(first.astype(int)) > 0).all()


def test_decoder_gives_back_the_simulated_points(scans):
    for scan in scans:
        stamp, arr = _decode(scan)
        p = scan.points
        assert stamp.host == pytest.approx(scan.stamp, abs=1e-6)
        assert arr.shape[0] == p.shape[0] > 1000
        xyz = np.column_stack([p["x"], p["y"], p["z"]])
        assert np.abs(arr[:, :3] - xyz).max() < 0.002  # m
        az_dec = np.degrees(np.arctan2(-arr[:, 1], arr[:, 0]))
        az_sim = np.degrees(np.arctan2(-p["y"], p["x"]))
        d_az = np.abs((az_dec - az_sim + 180.0) % 360.0 - 180.0)
        assert d_az.max() < 0.01  # deg
        assert np.array_equal(arr[:, 6].astype(int), p["ring"].astype(int))
        assert np.array_equal(arr[:, 3], p["intensity"])
        assert np.abs(arr[:, 4] - p["time"]).max() < 1e-5  # s, relative to the stamp


def _to_world(world, scan, lever_arm=(-0.28, 0.0, -0.57), waterline=0.30):
    """Sensor points -> NED (north, east, up above the water) with the true pose per point."""
    p = scan.points
    rel = scan.stamp + p["time"].astype(np.float64) - 1_686_909_600.0
    n, e, h = world.usv.pose(rel)
    roll, pitch, heave = world.waves.at(rel)
    r_nb = np.stack([rotation_matrix(a, b, c) for a, b, c in zip(roll, pitch, h, strict=False)])
    body = np.column_stack([n, e, -(waterline + heave)])
    origin = body + np.einsum("kij,j->ki", r_nb, np.asarray(lever_arm))
    xyz = np.column_stack([p["x"], -p["y"], -p["z"]])  # FLU -> FRD
    ned = origin + np.einsum("kij,kj->ki", r_nb, xyz)
    return ned[:, 0], ned[:, 1], -ned[:, 2]


def _segment_distance(pn, pe, poly):
    best = np.full(pn.shape, np.inf)
    for a, b in itertools.pairwise(poly):
        d = b - a
        f = np.clip(((pn - a[0]) * d[0] + (pe - a[1]) * d[1]) / (d @ d), 0.0, 1.0)
        best = np.minimum(best, np.hypot(pn - a[0] - f * d[0], pe - a[1] - f * d[1]))
    return best


def test_returns_lie_on_the_scene_objects(scans):
    world = make_world(5, 5.0)
    kinds = set(np.concatenate([s.kinds for s in scans]).tolist())
    assert "wall" in kinds and "building" not in kinds
    for scan in scans:
        n, e, up = _to_world(world, scan)
        wall = scan.kinds == "wall"
        dist = np.min([_segment_distance(n[wall], e[wall], w) for w in world.walls], axis=0)
        assert np.quantile(dist, 0.99) < 0.08 and dist.max() < 0.15  # 2 cm range noise
        assert up[wall].min() > -0.1 and up[wall].max() < 2.6
        # moored hulls: inside their boxes (+ noise)
        for b in world.moored:
            sel = scan.object_ids == b.object_id
            if not sel.any():
                continue
            s = b.shape
            c, si = np.cos(s.yaw), np.sin(s.yaw)
            x = (n[sel] - s.center[0]) * c + (e[sel] - s.center[1]) * si
            y = -(n[sel] - s.center[0]) * si + (e[sel] - s.center[1]) * c
            assert np.abs(x).max() < s.length / 2 + 0.15 and np.abs(y).max() < s.width / 2 + 0.15
        crest = scan.kinds == "water"
        assert np.abs(up[crest]).max(initial=0.0) < 0.15  # wave-crest returns at the surface


def test_decoded_azimuths_interpolate_at_the_packet_step():
    block = np.array([[1000 + 30 * k for k in range(12)]])
    az = decoded_azimuths(block)
    assert az.shape == (1, 12, 2, 16)
    assert az[0, 0, 0, 0] == 1000 and az[0, 0, 1, 0] == 1015  # half a block later
    assert az[0, 11, 0, 15] == round(1330 + 30 * 15 * 2.304 / 110.592)


def test_bad_rpm():
    with pytest.raises(ValueError, match="rpm"):
        Vlp16Recorder(make_world(5, 5.0), start=START, rpm=50.0)
