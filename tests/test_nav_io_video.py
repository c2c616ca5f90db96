"""Video frame timestamps: rate-based (thesis D1 case, with start/end time and offset) on an
MJPG AVI written by cv2.VideoWriter and an image sequence without container times, and
container timestamps on a variable-frame-rate file written by PyAV with known pts."""

from __future__ import annotations

import os
from fractions import Fraction

import av
import cv2
import numpy as np
import pytest

from usvfast.nav.video import VideoReader

T0 = 1_675_159_200.0  # 2023-01-31 10:00 UTC (D1's day)
W, H = 64, 48


def _level(image):
    return float(image.mean())


@pytest.fixture(scope="module")
def avi(tmp_path_factory):
    path = tmp_path_factory.mktemp("video") / "cam.avi"
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 4.0, (W, H))
    assert writer.isOpened()
    for i in range(10):
        writer.write(np.full((H, W, 3), 20 * i, np.uint8))
    writer.release()
    return path


def test_rate_times_with_start_and_offset(avi):
    reader = VideoReader(avi, start_time=T0, offset=-0.4, time_base="rate")
    frames = list(reader)
    assert [f.index for f in frames] == list(range(10))
    np.testing.assert_allclose([f.time for f in frames], T0 - 0.4 + np.arange(10) / 4.0, atol=1e-9)
    # Frame content in order (JPEG: approximately the written grey level).
    np.testing.assert_allclose([_level(f.image) for f in frames], 20 * np.arange(10), atol=3)
    assert reader.used_container == 0 and reader.damaged == 0


def test_end_time_and_file_mtime_d1(avi):
    # D1: only the time the file was written is known; the first frame is duration earlier.
    end = T0 + 100.0
    times = VideoReader(avi, end_time=end).times()
    np.testing.assert_allclose(times, end - 10 / 4.0 + np.arange(10) / 4.0, atol=1e-9)
    os.utime(avi, (end, end))
    np.testing.assert_allclose(VideoReader(avi).times(), times, atol=1e-6)


def test_skip_until_and_fps_override(avi):
    frames = list(VideoReader(avi, start_time=T0, fps=5.0, skip_until=T0 + 1.0, time_base="rate"))
    assert [f.index for f in frames] == [5, 6, 7, 8, 9]
    np.testing.assert_allclose([f.time for f in frames], T0 + np.arange(5, 10) / 5.0, atol=1e-9)
    np.testing.assert_allclose([_level(f.image) for f in frames], 20 * np.arange(5, 10), atol=3)


def test_image_sequence_needs_fps(tmp_path):
    for i in range(5):
        cv2.imwrite(str(tmp_path / f"f_{i:03d}.png"), np.full((8, 8, 3), 40 * i, np.uint8))
    pattern = tmp_path / "f_%03d.png"
    # OpenCV invents a 25 fps clock for image sequences; the given fps overrides it.
    reader = VideoReader(pattern, start_time=T0, fps=4.0)
    frames = list(reader)
    assert reader.used_container == 0
    np.testing.assert_array_equal([f.time for f in frames], T0 + np.arange(5) / 4.0)
    np.testing.assert_array_equal([f.image[0, 0, 0] for f in frames], 40 * np.arange(5))


def test_container_timestamps_variable_rate(tmp_path):
    path = tmp_path / "vfr.mkv"
    pts_ms = [0, 100, 250, 260, 700, 1000]
    with av.open(str(path), "w") as out:
        stream = out.add_stream("mjpeg", rate=10)
        stream.width, stream.height, stream.pix_fmt = W, H, "yuvj420p"
        stream.codec_context.time_base = Fraction(1, 1000)
        stream.time_base = Fraction(1, 1000)
        for i, p in enumerate(pts_ms):
            rgb = np.full((H, W, 3), 30 * i, np.uint8)
            frame = av.VideoFrame.from_ndarray(rgb, format="rgb24").reformat(format="yuvj420p")
            frame.pts, frame.time_base = p, Fraction(1, 1000)
            for packet in stream.encode(frame):
                out.mux(packet)
        for packet in stream.encode():
            out.mux(packet)
    reader = VideoReader(path, start_time=T0, offset=0.05)
    frames = list(reader)
    assert reader.used_container == len(pts_ms)
    np.testing.assert_allclose(
        [f.time for f in frames], T0 + 0.05 + np.array(pts_ms) / 1000.0, atol=1e-6
    )
    np.testing.assert_allclose([_level(f.image) for f in frames], 30 * np.arange(6), atol=3)
    # Forcing the rate ignores the container's timing (what D1 had to do).
    rate = VideoReader(path, start_time=T0, time_base="rate", fps=10.0).times()
    np.testing.assert_allclose(rate, T0 + np.arange(6) / 10.0, atol=1e-9)


def test_bad_arguments(avi, tmp_path):
    with pytest.raises(ValueError, match="video: no such file"):
        VideoReader(tmp_path / "none.avi", start_time=T0)
    with pytest.raises(ValueError, match="start_time, end_time"):
        VideoReader(avi, start_time=T0, end_time=T0)
    with pytest.raises(ValueError, match="time_base"):
        VideoReader(avi, start_time=T0, time_base="pts")
    with pytest.raises(ValueError, match="fps"):
        VideoReader(avi, start_time=T0, fps=-1.0)
    junk = tmp_path / "junk.avi"
    junk.write_bytes(b"not a video")
    with pytest.raises(ValueError, match="video: OpenCV cannot open"):
        VideoReader(junk, start_time=T0)
