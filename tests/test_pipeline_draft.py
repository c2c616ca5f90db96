"""`usvfast init`: a config drafted from a bag's topics (usvfast.pipeline.draft)."""

from __future__ import annotations

import shutil
import sys
from functools import reduce
from importlib import resources
from operator import xor
from pathlib import Path

import numpy as np
import pytest
from rosbags.rosbag1 import Writer as Writer1
from rosbags.rosbag2 import Writer as Writer2
from typer.testing import CliRunner

from usvfast.camera.calibration import CameraModel
from usvfast.cli import app
from usvfast.lidar.frame import POINT_DTYPE
from usvfast.lidar.readers import lidar_typestore, make_header, points_to_pointcloud2
from usvfast.nav.bags import bag_typestore
from usvfast.pipeline import Pipeline, load_config
from usvfast.pipeline.draft import VELODYNE_MODELS, draft_config, write_draft

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

HARBOUR = Path(str(resources.files("usvfast") / "data" / "harbour"))
T0 = 1_686_909_600.0
K = np.array([[412.5, 0.0, 330.25], [0.0, 410.0, 241.5], [0.0, 0.0, 1.0]])
D = np.array([-0.21, 0.05, 0.001, -0.002, 0.0])


@pytest.fixture(scope="module")
def harbour_draft(tmp_path_factory):
    """The bundled bag copied into a folder, drafted into recording.toml there."""
    root = tmp_path_factory.mktemp("draft")
    shutil.copytree(HARBOUR / "bag", root / "bag")
    draft = write_draft(root / "bag", root / "recording.toml")
    return root, draft


def test_bundled_bag_streams_match_its_config(harbour_draft):
    root, draft = harbour_draft
    bundled = tomllib.loads((HARBOUR / "recording.toml").read_text())
    want = {s["id"]: s["topic"] for s in bundled["stream"]}
    assert {sid: topic for sid, topic, _ in draft.streams} == want
    cfg = load_config(root / "recording.toml")
    assert cfg.navigation == ("gnss",)
    assert cfg.attitude == "imu"
    assert [s.id for s in cfg.streams_of("lidar")] == ["lidar"]
    assert cfg.recording.stream("lidar").options["model"] == "VLP-16"  # from byte 1205
    assert cfg.recording.stream("lidar").path == (root / "bag").resolve()
    assert cfg.detector["backend"] == "none"
    assert "navigation: 301 position fixes and 300 headings" in draft.notes


def test_bundled_calibration_is_the_bags_camera_info(harbour_draft):
    root, draft = harbour_draft
    ours = CameraModel.load(root / "camera_info.yaml")
    shipped = CameraModel.load(HARBOUR / "camera_info.yaml")
    assert ours.image_size == shipped.image_size
    np.testing.assert_array_equal(ours.camera_matrix, shipped.camera_matrix)
    np.testing.assert_array_equal(ours.dist_coeffs, shipped.dist_coeffs)
    assert draft.calibration is not None


def test_drafted_config_runs(harbour_draft):
    root, _ = harbour_draft
    start = np.loadtxt(HARBOUR / "truth.csv", delimiter=",", skiprows=1, usecols=0).min()
    pipe = Pipeline(load_config(root / "recording.toml"))
    list(pipe.run(end=float(start) + 8.0))
    assert pipe.summary["detections"]["lidar"] > 0  # the LiDAR chain ran on the packets
    assert pipe.summary["tracks"] > 0


def test_placeholders_are_marked(harbour_draft):
    _, draft = harbour_draft
    text = draft.text
    assert text.count("lever_arm = [0.0, 0.0, 0.0]  # MEASURE") == 3  # gnss, lidar, camera
    assert text.count("waterline_height = 0.3  # MEASURE") == 2
    assert 'backend = "none"  # SET' in text


def _ros1_bag(path: Path, *, factory: int, k: np.ndarray, heading: bool) -> None:
    """A ROS 1 bag: NavSatFix (and NMEA with HDT and a QuaternionStamped heading when
    `heading`), an IMU, a VelodyneScan
    with `factory` as its model byte, a PointCloud2, three image topics and two CameraInfo
    topics (uppercase ROS 1 fields)."""
    ts = lidar_typestore(ros1=True)
    T = ts.types
    with Writer1(path) as w:

        def put(topic: str, msgtype: str, msgs: list, store=ts) -> None:
            conn = w.add_connection(topic, msgtype, typestore=store)
            for i, m in enumerate(msgs):
                w.write(conn, int((T0 + 0.1 * i) * 1e9), bytes(store.serialize_ros1(m, msgtype)))

        h = [make_header(ts, T0 + 0.1 * i, "base") for i in range(3)]
        status = T["sensor_msgs/msg/NavSatStatus"](status=0, service=1)
        fixes = [
            T["sensor_msgs/msg/NavSatFix"](
                header=h[i],
                status=status,
                latitude=63.44 + 1e-6 * i,
                longitude=10.40,
                altitude=40.0,
                position_covariance=np.zeros(9),
                position_covariance_type=0,
            )
            for i in range(3)
        ]
        put("/fix", "sensor_msgs/msg/NavSatFix", fixes)
        if heading:
            nav = bag_typestore(ros2=False)
            hdt = "GPHDT,123.4,T"
            sentence = f"${hdt}*{reduce(xor, hdt.encode()):02X}"
            nmea = [
                nav.types["nmea_msgs/msg/Sentence"](
                    header=make_header(nav, T0 + 0.1 * i, "gnss"), sentence=sentence
                )
                for i in range(3)
            ]
            put("/heading/nmea", "nmea_msgs/msg/Sentence", nmea, nav)
            yaw = T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0)
            q = T["geometry_msgs/msg/QuaternionStamped"](header=h[0], quaternion=yaw)
            put("/heading", "geometry_msgs/msg/QuaternionStamped", [q])
        v3 = T["geometry_msgs/msg/Vector3"]
        imu = T["sensor_msgs/msg/Imu"](
            header=h[0],
            orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
            orientation_covariance=np.zeros(9),
            angular_velocity=v3(x=0.0, y=0.0, z=0.0),
            angular_velocity_covariance=np.zeros(9),
            linear_acceleration=v3(x=0.0, y=0.0, z=9.81),
            linear_acceleration_covariance=np.zeros(9),
        )
        put("/imu/data", "sensor_msgs/msg/Imu", [imu])
        raw = T["sensor_msgs/msg/Imu"](
            header=h[0],
            orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=0.0),
            orientation_covariance=np.r_[-1.0, np.zeros(8)],  # REP-145: no orientation
            angular_velocity=v3(x=0.0, y=0.0, z=0.0),
            angular_velocity_covariance=np.zeros(9),
            linear_acceleration=v3(x=0.0, y=0.0, z=9.81),
            linear_acceleration_covariance=np.zeros(9),
        )
        put("/imu/acc_gyro", "sensor_msgs/msg/Imu", [raw])  # sorts first: not the attitude
        data = np.zeros(1206, np.uint8)
        data[1204], data[1205] = 0x37, factory
        stamp = T["builtin_interfaces/msg/Time"](sec=int(T0), nanosec=0)
        packet = T["velodyne_msgs/msg/VelodynePacket"](stamp=stamp, data=data)
        scan = T["velodyne_msgs/msg/VelodyneScan"](header=h[0], packets=[packet])
        put("/velodyne_packets", "velodyne_msgs/msg/VelodyneScan", [scan])
        cloud = points_to_pointcloud2(T0, np.zeros(4, POINT_DTYPE), "velodyne", ts)
        put("/points", "sensor_msgs/msg/PointCloud2", [cloud])
        img = T["sensor_msgs/msg/Image"](
            header=h[0], height=2, width=2, encoding="mono8", is_bigendian=0, step=2,
            data=np.zeros(4, np.uint8),
        )  # fmt: skip
        put("/cam/left/image_raw", "sensor_msgs/msg/Image", [img, img])
        put("/aux/image", "sensor_msgs/msg/Image", [img, img, img])
        jpeg = T["sensor_msgs/msg/CompressedImage"](
            header=h[0], format="jpeg", data=np.zeros(4, np.uint8)
        )
        put("/cam/left/image_raw/compressed", "sensor_msgs/msg/CompressedImage", [jpeg])
        roi = T["sensor_msgs/msg/RegionOfInterest"](
            x_offset=0, y_offset=0, height=0, width=0, do_rectify=False
        )

        def info(kk: np.ndarray) -> object:
            return T["sensor_msgs/msg/CameraInfo"](
                header=h[0], height=480, width=640, distortion_model="plumb_bob", D=D,
                K=kk.ravel(), R=np.eye(3).ravel(), P=np.hstack([kk, np.zeros((3, 1))]).ravel(),
                binning_x=0, binning_y=0, roi=roi,
            )  # fmt: skip

        put("/cam/left/camera_info", "sensor_msgs/msg/CameraInfo", [info(k)])
        put("/aux/camera_info", "sensor_msgs/msg/CameraInfo", [info(2 * k)])


def test_ros1_bag_every_kind(tmp_path):
    bag = tmp_path / "run.bag"
    _ros1_bag(bag, factory=0x21, k=K, heading=True)
    draft = write_draft(bag, tmp_path / "cfg" / "run.toml")
    by_id = {sid: (topic, msgtype) for sid, topic, msgtype in draft.streams}
    assert by_id["gnss1"][0] == "/fix" and by_id["gnss2"][0] == "/heading/nmea"
    assert by_id["lidar1"] == ("/points", "sensor_msgs/msg/PointCloud2")
    assert by_id["lidar2"] == ("/velodyne_packets", "velodyne_msgs/msg/VelodyneScan")
    # the image nearest in name to a CameraInfo, compressed first (not the most frequent)
    assert by_id["camera"][0] == "/cam/left/image_raw/compressed"
    assert "# other image topics: /aux/image, /cam/left/image_raw" in draft.text
    cfg = load_config(tmp_path / "cfg" / "run.toml")
    assert cfg.navigation == ("gnss1", "gnss2", "heading")
    assert by_id["heading"] == ("/heading", "geometry_msgs/msg/QuaternionStamped")
    assert cfg.recording.stream("heading").options == {"yaw_convention": "enu"}
    assert cfg.recording.stream("lidar2").options["model"] == "HDL-32E"
    assert cfg.recording.stream("lidar2").path == bag.resolve()  # outside the config's folder
    cam = CameraModel.load(tmp_path / "cfg" / "camera_info.yaml")  # /cam/left's, ROS 1 K, D
    np.testing.assert_array_equal(cam.camera_matrix, K)
    np.testing.assert_array_equal(cam.dist_coeffs, D)
    assert cam.image_size == (640, 480)
    assert "navigation: 3 position fixes and 3 headings" in draft.notes
    assert cfg.attitude == "imu" and by_id["imu"][0] == "/imu/data"
    assert "# /imu/acc_gyro: an IMU without an orientation estimate" in draft.text


@pytest.mark.parametrize("factory", sorted(VELODYNE_MODELS))
def test_velodyne_models_from_the_factory_byte(tmp_path, factory):
    bag = tmp_path / "run.bag"
    _ros1_bag(bag, factory=factory, k=K, heading=True)
    cfg_text = draft_config(bag, tmp_path).text
    assert f'model = "{VELODYNE_MODELS[factory]}"' in cfg_text


def test_unknown_model_uncalibrated_camera_and_no_heading_are_notes(tmp_path):
    bag = tmp_path / "run.bag"
    _ros1_bag(bag, factory=0x99, k=np.zeros((3, 3)), heading=False)
    draft = write_draft(bag, tmp_path / "run.toml")
    assert draft.calibration is None
    assert not (tmp_path / "camera_info.yaml").exists()
    assert any("/velodyne_packets: unknown Velodyne model" in n for n in draft.notes)
    assert any("no camera calibration found" in n for n in draft.notes)
    assert any(n.startswith("navigation:") and "heading" in n for n in draft.notes)
    cfg = load_config(tmp_path / "run.toml")  # loads: the camera is off until calibrated
    assert cfg.camera["enabled"] is False


def _bag2(path: Path, topics: dict[str, str]) -> None:
    """A ROS 2 bag with one message on each topic (NMEA Sentence or PointCloud2)."""
    ts = bag_typestore()
    with Writer2(path, version=8) as w:
        for topic, msgtype in topics.items():
            conn = w.add_connection(topic, msgtype, typestore=ts)
            if msgtype == "nmea_msgs/msg/Sentence":
                msg = ts.types[msgtype](header=make_header(ts, T0, "g"), sentence="$GPHDT,1,T")
            else:
                msg = points_to_pointcloud2(T0, np.zeros(1, POINT_DTYPE), "v", ts)
            w.write(conn, int(T0 * 1e9), bytes(ts.serialize_cdr(msg, msgtype)))


def test_bags_without_navigation_or_sensors_are_refused(tmp_path):
    _bag2(tmp_path / "lidar_only", {"/points": "sensor_msgs/msg/PointCloud2"})
    with pytest.raises(ValueError, match=r"no navigation topic .*/points"):
        draft_config(tmp_path / "lidar_only", tmp_path)
    _bag2(tmp_path / "nav_only", {"/nmea": "nmea_msgs/msg/Sentence"})
    with pytest.raises(ValueError, match=r"no LiDAR .* or camera"):
        draft_config(tmp_path / "nav_only", tmp_path)
    with pytest.raises(ValueError, match="bag"):
        draft_config(tmp_path / "missing", tmp_path)


def test_existing_files_need_force(harbour_draft, tmp_path):
    root, _ = harbour_draft
    out = tmp_path / "recording.toml"
    out.write_text("# mine\n")
    with pytest.raises(ValueError, match=r"out: .*recording.toml exists .*--force"):
        write_draft(root / "bag", out)
    assert out.read_text() == "# mine\n"
    write_draft(root / "bag", out, force=True)
    assert out.read_text().startswith("# Drafted by `usvfast init`")


def test_cli_init(harbour_draft, tmp_path):
    root, _ = harbour_draft
    out = tmp_path / "mine" / "recording.toml"
    res = CliRunner().invoke(app, ["init", str(root / "bag"), "--out", str(out)])
    assert res.exit_code == 0, res.output
    assert "/velodyne_packets" in res.output and "301 position fixes" in res.output
    assert out.is_file() and (out.parent / "camera_info.yaml").is_file()
    again = CliRunner().invoke(app, ["init", str(root / "bag"), "--out", str(out)])
    assert again.exit_code != 0


def test_cli_init_error_is_one_line(monkeypatch, capsys, tmp_path):
    from usvfast import cli

    monkeypatch.setattr(sys, "argv", ["usvfast", "init", str(tmp_path / "no_such_bag")])
    with pytest.raises(SystemExit) as info:
        cli.main()
    err = capsys.readouterr().err
    assert info.value.code == 2
    assert err.startswith("usvfast: error: bag") and err.count("\n") == 1


@pytest.fixture(scope="module")
def d1(tmp_path_factory):
    """A 2 s simulated recording with the thesis's D1 files (pcap, mp4 + times, NMEA)."""
    from usvfast.sim.recording import SimulationOptions, simulate

    out = tmp_path_factory.mktemp("d1") / "rec"
    simulate(out, SimulationOptions(seed=11, duration=2.0, d1=True))
    return out


def test_d1_folder_matches_the_simulators_config(d1, tmp_path):
    folder = tmp_path / "d1"
    shutil.copytree(d1 / "d1", folder)
    shutil.copy(d1 / "camera_info.yaml", folder / "cam.yaml")
    (folder / "notes.txt").write_text("not an NMEA log\n")
    draft = write_draft(folder, tmp_path / "run.toml")
    assert draft.streams == [
        ("gnss", "gnss.nmea", "nmea"),
        ("lidar", "lidar.pcap", "pcap"),
        ("camera", "camera.mp4", "video_times"),
    ]
    ours = load_config(tmp_path / "run.toml")
    sim = load_config(d1 / "recording-d1.toml")
    for sid in ("gnss", "lidar", "camera"):
        a, b = ours.recording.stream(sid), sim.recording.stream(sid)
        assert a.path is not None and b.path is not None
        assert (a.type, a.path.name) == (b.type, b.path.name)
    assert ours.recording.stream("camera").options == sim.recording.stream("camera").options
    assert ours.recording.stream("lidar").options == {"model": "VLP-16"}  # the sim's default
    assert ours.camera["calibration"] == (folder / "cam.yaml").resolve()
    assert any(n.startswith("navigation: ") and "headings" in n for n in draft.notes)
    assert draft.calibration is None  # the folder's own file is named, not copied


def test_d1_folder_without_times_or_nmea(d1, tmp_path):
    folder = tmp_path / "d1"
    shutil.copytree(d1 / "d1", folder)
    (folder / "camera_times.csv").unlink()
    draft = draft_config(folder, tmp_path)
    assert [s[0] for s in draft.streams] == ["gnss", "lidar"]
    assert any("no frame,time CSV beside camera.mp4" in n for n in draft.notes)
    (folder / "lidar.pcap").write_bytes(b"")  # an empty capture: its model to SET
    assert any(
        "lidar.pcap: unknown Velodyne model" in n for n in draft_config(folder, tmp_path).notes
    )
    (folder / "gnss.nmea").unlink()
    with pytest.raises(ValueError, match=r"no NMEA log .*lidar.pcap"):
        draft_config(folder, tmp_path)
