"""`usvfast lidar` on the real capture and on a simulated ROS2 bag with poses."""

from __future__ import annotations

import csv

import numpy as np
from typer.testing import CliRunner

from usvfast.cli import app
from usvfast.lidar import VLP16Simulator, harbour_scene, straight_run, write_pointcloud2_bag

from conftest import SHARED_DATA

runner = CliRunner()


def test_cli_on_real_pcap():
    result = runner.invoke(
        app, ["lidar", str(SHARED_DATA / "lidar" / "velodyne_hdl32e.pcap"), "--height", "1.8"]
    )
    assert result.exit_code == 0, result.output
    lines = result.output.splitlines()
    assert lines[1].split()[2] == "18154" and lines[2].split()[2] == "1425"
    assert "2 frames, 0 damaged records skipped" in result.output


def test_cli_on_simulated_bag(tmp_path):
    scene = harbour_scene(seed=4, floats=6)
    poses, stamps = straight_run(8, t0=1_700_000_000.0)
    sim = VLP16Simulator(scene, seed=4)
    frames = [sim.scan(p, t).frame for p, t in zip(poses, stamps, strict=True)]
    bag = write_pointcloud2_bag(tmp_path / "sim", frames)
    pose_csv = tmp_path / "poses.csv"
    with open(pose_csv, "w") as fh:
        fh.write("time,north,east,heading\n")
        for t, p in zip(stamps, poses, strict=True):
            fh.write(f"{t},{p[0]},{p[1]},{p[2]}\n")
    out = tmp_path / "det.csv"
    result = runner.invoke(app, ["lidar", str(bag), "--poses", str(pose_csv), "--csv", str(out)])
    assert result.exit_code == 0, result.output
    with open(out) as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) >= 4
    floats = np.array([o.center for o in scene.objects if o.kind == "float"])
    for r in rows:
        pos = np.array([float(r["north"]), float(r["east"])])
        assert np.linalg.norm(floats - pos, axis=1).min() < 0.5  # each detection is a float
        assert r["sensor_id"] == "lidar" and int(r["n_points"]) >= 15
