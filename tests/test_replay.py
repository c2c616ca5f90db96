"""Recording replay: the merge is the stable sort of all items (hypothesis), nothing is lost,
offsets are applied, it is lazy (works on an endless stream), poses are attached at each
item's own time, and bad recording files fail naming the key."""

from __future__ import annotations

import itertools
from pathlib import Path

import cv2
import gpxpy
import gpxpy.gpx
import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from usvfast import DimensionError, NonFiniteError, TimeOrderError
from usvfast.nav._damage import DamagedRecordsWarning
from usvfast.nav.pose import PoseGapError
from usvfast.nav.replay import Recording, Replay, load_recording
from usvfast.nav.stream_types import RecordingError, StreamSpec, register_stream_type

_SOURCES: dict[str, object] = {}


def _open_memory(spec: StreamSpec, decode: bool):
    src = _SOURCES[spec.options["key"]]
    return src() if callable(src) else src


register_stream_type("memory", _open_memory, needs_path=False, options=["key"])


def _recording(streams, offsets, window=16):
    specs = []
    for k, (items, off) in enumerate(zip(streams, offsets, strict=True)):
        key = f"s{k}-{id(items)}"
        _SOURCES[key] = items
        specs.append(
            StreamSpec(id=f"s{k}", type="memory", path=None, clock_offset=off, options={"key": key})
        )
    return Recording("test", tuple(specs), reorder_window=window)


times_lists = st.lists(
    st.lists(st.integers(0, 30).map(lambda x: x / 4.0), max_size=25).map(sorted),
    min_size=1,
    max_size=5,
)


@given(times_lists, st.data())
def test_merge_is_the_stable_sort(streams, data):
    offsets = data.draw(
        st.lists(
            st.sampled_from([0.0, 0.25, -0.5, 1.0]), min_size=len(streams), max_size=len(streams)
        )
    )
    inputs = [[(t, (k, i)) for i, t in enumerate(ts)] for k, ts in enumerate(streams)]
    rec = _recording(inputs, offsets)
    got = [(item.time, item.stream, item.index, item.data) for item in Replay(rec)]
    # Reference: Python's stable sort of every item by (time + offset, stream, index).
    want = sorted(
        (
            (t + offsets[k], f"s{k}", i, (k, i))
            for k, ts in enumerate(streams)
            for i, t in enumerate(ts)
        ),
        key=lambda x: (x[0], int(x[1][1:]), x[2]),
    )
    assert got == want
    assert [g[0] for g in got] == sorted(g[0] for g in got)


@given(st.lists(st.integers(0, 200), min_size=1, max_size=60), st.integers(0, 8))
def test_reorder_window_sorts_local_jitter(base, jitter):
    # A stream whose items are displaced by at most `jitter` positions comes out sorted and
    # complete when the window is at least that large.
    times = sorted(base)
    # Reverse consecutive blocks of jitter + 1 items: no item moves more than `jitter` places.
    perm = []
    for start in range(0, len(times), jitter + 1):
        perm.extend(reversed(range(start, min(start + jitter + 1, len(times)))))
    shuffled = [(float(times[p]), p) for p in perm]
    rec = _recording([shuffled], [0.0], window=jitter)
    replay = Replay(rec)
    got = list(replay)
    assert [g.time for g in got] == [float(t) for t in times]
    assert sorted(g.data for g in got) == list(range(len(times)))
    assert replay.counts["s0"].out_of_order == 0


def test_out_of_order_beyond_window_counted():
    stream = [(float(t), t) for t in [0, 1, 2, 3, 4, 5]] + [(1.5, "late"), (6.0, 6)]
    replay = Replay(_recording([stream], [0.0], window=2))
    with pytest.warns(DamagedRecordsWarning, match="reorder window"):
        got = [item.data for item in replay]
    assert got == [0, 1, 2, 3, 4, 5, 6]
    assert replay.counts["s0"].out_of_order == 1 and replay.counts["s0"].yielded == 7


def test_time_window():
    stream = [(float(t), t) for t in range(10)]
    rec = _recording([stream, [(4.5, "x")]], [0.0, 0.0])
    got = [(i.time, i.stream, i.index) for i in Replay(rec, start=3.0, end=5.0)]
    assert got == [(3.0, "s0", 3), (4.0, "s0", 4), (4.5, "s1", 0), (5.0, "s0", 5)]
    with pytest.raises(ValueError, match="start, end"):
        Replay(rec, start=5.0, end=3.0)
    with pytest.raises(ValueError, match="end: expected a finite"):
        Replay(rec, end=float("nan"))


def test_lazy_on_endless_stream():
    def endless():
        for i in itertools.count():
            yield float(i), i

    rec = _recording([endless, [(2.5, "x")]], [0.0, 0.0])
    got = [(i.time, i.data) for i in itertools.islice(Replay(rec), 6)]
    assert got == [(0.0, 0), (1.0, 1), (2.0, 2), (2.5, "x"), (3.0, 3), (4.0, 4)]
    # An end time stops an endless replay.
    assert len(list(Replay(rec, end=99.5))) == 101


class _Pose:
    """Pose track covering [10, 20] s: pose_at raises ValueError outside."""

    def pose_at(self, t):
        if not 10.0 <= t <= 20.0:
            raise ValueError(f"t={t} outside the pose track")
        return ("pose", t)


def test_pose_at_item_time_and_outside():
    stream = [(float(t), t) for t in range(8, 23, 2)]
    rec = _recording([stream, [(15.0, "cam")]], [0.0, 0.5])
    replay = Replay(rec, _Pose())
    items = list(replay)
    for it in items:
        assert it.pose == (("pose", it.time) if 10.0 <= it.time <= 20.0 else None)
    assert [it.time for it in items if it.stream == "s1"] == [15.5]
    assert replay.counts["s0"].no_pose == 2 and replay.counts["s0"].yielded == 8
    skipping = Replay(rec, _Pose(), skip_without_pose=True)
    kept = list(skipping)
    assert len(kept) == 7 and all(it.pose is not None for it in kept)
    assert skipping.counts["s0"].no_pose == 2 and skipping.counts["s0"].yielded == 6
    with pytest.raises(TypeError, match="pose_track"):
        Replay(rec, object())


class _BrokenPose:
    """A pose source failing with errors other than "outside the coverage"."""

    def __init__(self, exc):
        self.exc = exc

    def pose_at(self, t):
        raise self.exc


@pytest.mark.parametrize(
    "exc",
    [
        NonFiniteError("yaw: contains a non-finite value (NaN or inf)"),
        DimensionError("position: expected shape (3,), got (2,)"),
        TimeOrderError("time: must be sorted ascending"),
        KeyError("yaw"),
    ],
)
def test_pose_source_errors_are_not_counted_as_no_pose(exc):
    # These used to be swallowed (ValueError subclasses) and counted as no_pose.
    rec = _recording([[(float(t), t) for t in range(3)]], [0.0])
    with pytest.raises(type(exc)):
        list(Replay(rec, _BrokenPose(exc)))


def test_pose_gap_error_is_no_pose():
    rec = _recording([[(float(t), t) for t in range(3)]], [0.0])
    replay = Replay(rec, _BrokenPose(PoseGapError("t: outside the pose track")))
    assert [it.pose for it in replay] == [None, None, None]
    assert replay.counts["s0"].no_pose == 3


def test_replay_with_the_recordings_pose_track(tmp_path):
    """GPX navigation: the pose at each item's own time is the linear interpolation of the
    fixes (numpy.interp as the reference); items past the track have no pose."""
    from usvfast.nav.fixes import recording_pose_track

    _write_files(tmp_path)
    path = tmp_path / "rec.toml"
    text = RECORDING.format(t0=T0 + 8.0).replace('name = "pier test"', "max_pose_gap = 1.5")
    path.write_text(text)
    rec = load_recording(path)
    assert rec.max_pose_gap == 1.5
    track = recording_pose_track(rec)
    replay = Replay(rec, track)
    items = list(replay)
    fix_t = T0 + np.arange(11.0)
    fix_lat = 63.43 + np.arange(11) * 1e-5
    for it in items:
        if it.time > fix_t[-1]:
            assert it.pose is None
        else:
            assert it.pose.lat_deg[0] == pytest.approx(
                np.interp(it.time, fix_t, fix_lat), abs=1e-12
            )
            assert it.pose.time[0] == it.time
    # cam: 12 frames from T0 + 8.3 every 0.25 s; those after T0 + 10 have no pose.
    assert replay.counts["cam"].no_pose == int(np.sum(T0 + 8.3 + np.arange(12) / 4.0 > fix_t[-1]))
    assert replay.counts["gnss"].no_pose == 0


# --- recordings from TOML with real files ----------------------------------------------------

T0 = 1_686_909_600.0


def _write_files(tmp: Path):
    gpx = gpxpy.gpx.GPX()
    trk = gpxpy.gpx.GPXTrack()
    seg = gpxpy.gpx.GPXTrackSegment()
    gpx.tracks.append(trk)
    trk.segments.append(seg)
    from datetime import datetime, timezone

    for k in range(11):
        seg.points.append(
            gpxpy.gpx.GPXTrackPoint(
                63.43 + k * 1e-5, 10.39, time=datetime.fromtimestamp(T0 + k, tz=timezone.utc)
            )
        )
    (tmp / "track.gpx").write_text(gpx.to_xml())
    writer = cv2.VideoWriter(str(tmp / "cam.avi"), cv2.VideoWriter_fourcc(*"MJPG"), 4.0, (32, 24))
    for i in range(12):
        writer.write(np.full((24, 32, 3), 10 * i, np.uint8))
    writer.release()


RECORDING = """
[recording]
name = "pier test"
navigation = "gnss"

[[stream]]
id = "gnss"
type = "gpx"
path = "track.gpx"
sensor_id = 1

[[stream]]
id = "cam"
type = "video"
path = "cam.avi"
start_time = {t0}
time_base = "rate"
clock_offset = 0.3
sensor_id = "hikvision"
[stream.mount]
lever_arm = [1.2, 0.0, -0.8]
ypr_deg = [90.0, 0.0, 0.0]
"""


def test_toml_recording_replay(tmp_path):
    _write_files(tmp_path)
    path = tmp_path / "rec.toml"
    path.write_text(RECORDING.format(t0=T0))
    rec = load_recording(path)
    assert rec.name == "pier test" and rec.navigation == "gnss"
    cam = rec.stream("cam")
    assert cam.mount.lever_arm.tolist() == [1.2, 0.0, -0.8]
    assert (cam.mount.yaw, cam.mount.pitch, cam.mount.roll) == (np.pi / 2, 0.0, 0.0)
    assert cam.path == tmp_path / "cam.avi" and cam.sensor_id == "hikvision"
    items = list(Replay(rec))
    assert len(items) == 11 + 12
    times = [it.time for it in items]
    assert times == sorted(times)
    cam_times = [it.time for it in items if it.stream == "cam"]
    np.testing.assert_allclose(cam_times, T0 + 0.3 + np.arange(12) / 4.0, atol=1e-9)
    gnss = [it for it in items if it.stream == "gnss"]
    assert [it.time for it in gnss] == [T0 + k for k in range(11)]
    assert gnss[3].data.lat_deg == pytest.approx(63.43 + 3e-5, abs=1e-12)
    assert gnss[0].sensor_id == 1 and gnss[0].mount is None
    # Equal times: the gnss stream (first in the file) comes first.
    assert items[0].stream == "gnss" and items[0].time == T0


BAD = [
    ("[[stream]]\nid = 'a'\ntype = 'radar'\npath = 'x'\n", "key 'type': 'radar'"),
    ("[[stream]]\nid = 'a'\ntype = 'gpx'\n", "key 'path'"),
    ("[[stream]]\nid = 'a'\ntype = 'bag'\npath = 'x.bag'\n", "key 'topic'"),
    ("[[stream]]\ntype = 'gpx'\npath = 'x'\n", "stream\\[0\\]: key 'id'"),
    (
        "[[stream]]\nid = 'a'\ntype = 'gpx'\npath = 'x'\nclock_offset = 'soon'\n",
        "key 'clock_offset'",
    ),
    ("[[stream]]\nid = 'a'\ntype = 'gpx'\npath = 'x'\nfps = 4\n", "key 'fps': not an option"),
    (
        "[[stream]]\nid = 'a'\ntype = 'gpx'\npath = 'x'\n[stream.mount]\nlever_arm = [1, 2]\n",
        "key 'mount.lever_arm'",
    ),
    (
        "[recording]\nmax_pose_gap = 0\n[[stream]]\nid = 'a'\ntype = 'gpx'\npath = 'x'\n",
        "key 'recording.max_pose_gap'",
    ),
    (
        "[[stream]]\nid = 'a'\ntype = 'gpx'\npath = 'x'\n"
        "[[stream]]\nid = 'a'\ntype = 'gpx'\npath = 'y'\n",
        "stream id 'a' is used twice",
    ),
    (
        "[recording]\nnavigation = 'gps'\n[[stream]]\nid = 'a'\ntype = 'gpx'\npath = 'x'\n",
        "key 'recording.navigation'",
    ),
    ("[recording]\nname = 'x'\n", "key 'stream'"),
    ("[[stream]\n", "not valid TOML"),
    ("[streams]\n", "key 'streams': unknown"),
]


@pytest.mark.parametrize(("text", "match"), BAD)
def test_bad_recordings_name_the_key(tmp_path, text, match):
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(RecordingError, match=match):
        load_recording(path)


def test_reader_errors_name_the_stream(tmp_path):
    _write_files(tmp_path)
    path = tmp_path / "rec.toml"
    path.write_text(RECORDING.format(t0='"yesterday"'))
    with pytest.raises(RecordingError, match="stream 'cam' \\(video\\): start_time"):
        list(Replay(load_recording(path)))
    path.write_text(RECORDING.format(t0=T0).replace("track.gpx", "gone.gpx"))
    with pytest.raises(RecordingError, match="stream 'gnss' \\(gpx\\): gpx: no such file"):
        list(Replay(load_recording(path)))


def test_missing_recording_file(tmp_path):
    with pytest.raises(RecordingError, match="cannot read"):
        load_recording(tmp_path / "none.toml")


def test_navigation_fixes_gpx_and_bag(tmp_path):
    from rosbags.rosbag2 import Writer as Writer2

    from usvfast.nav.bags import bag_typestore
    from usvfast.nav.fixes import navigation_fixes

    _write_files(tmp_path)
    ts = bag_typestore()
    T = ts.types
    lat = [63.1, 63.2, float("nan"), 63.4]
    status = [0, 2, 0, -1]
    with Writer2(tmp_path / "bag", version=9) as w:
        conn = w.add_connection("/fix", "sensor_msgs/msg/NavSatFix", typestore=ts)
        for i in range(4):
            msg = T["sensor_msgs/msg/NavSatFix"](
                header=T["std_msgs/msg/Header"](
                    stamp=T["builtin_interfaces/msg/Time"](sec=int(T0) + i, nanosec=0),
                    frame_id="gps",
                ),
                status=T["sensor_msgs/msg/NavSatStatus"](status=status[i], service=1),
                latitude=lat[i],
                longitude=10.0,
                altitude=5.0 + i,
                position_covariance=np.zeros(9),
                position_covariance_type=0,
            )
            w.write(conn, (int(T0) + i) * 10**9, bytes(ts.serialize_cdr(msg, msg.__msgtype__)))
    path = tmp_path / "rec.toml"
    path.write_text(
        RECORDING.format(t0=T0)
        + '\n[[stream]]\nid = "fix"\ntype = "bag"\npath = "bag"\ntopic = "/fix"\n'
        + "clock_offset = -0.25\n"
    )
    rec = load_recording(path)
    gnss = navigation_fixes(rec)
    assert gnss.stream == "gnss" and gnss.times.tolist() == [T0 + k for k in range(11)]
    np.testing.assert_array_equal(gnss.lat_deg, 63.43 + np.arange(11) * 1e-5)
    fix = navigation_fixes(rec, "fix")
    assert fix.times.tolist() == [T0 - 0.25, T0 + 0.75] and fix.no_fix == 2
    assert fix.lat_deg.tolist() == [63.1, 63.2] and fix.alt_m.tolist() == [5.0, 6.0]
    with pytest.raises(ValueError, match="holds VideoFrame records"):
        navigation_fixes(rec, "cam")
