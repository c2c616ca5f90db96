"""Test-time augmentation of the SSD (usvfast.shore.ssd_tta): tiles cover the frame with the
stated overlap; with a stand-in network that reports the bright blobs it sees at least a few
input pixels large (OpenCV's connected components, a second implementation of "where the
boats are"), the mirrored view maps back onto the frame, the tiles of an enlarged frame find
blobs too small for the whole-frame pass, each blob exactly once and with its exact box;
without any augmentation the result is the detector's own; bad arguments raise."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from usvfast.shore.pretrained import SsdDetector
from usvfast.shore.ssd_tta import TILE_OVERLAP, SsdTta, tile_origins


class BlobNet(SsdDetector):
    """A stand-in SsdDetector: its candidates are the bright (> 128) connected components of
    the image that are at least `min_px` wide and high once letterboxed to `input_size`
    (what a network of that input size could resolve), score 0.9, plus a copy shifted by
    one pixel (score 0.5) that NMS must remove."""

    def __init__(self, input_size=(320, 240), min_px=6.0):
        self.input_size = input_size
        self.conf_threshold = 0.3
        self.iou_threshold = 0.6
        self.top_k = 100
        self.letterbox = True
        self.min_px = min_px

    def candidates(self, image):
        h, w = image.shape[:2]
        s = min(self.input_size[0] / w, self.input_size[1] / h)
        n, _, stats, _ = cv2.connectedComponentsWithStats(
            (image[..., 1] > 128).astype(np.uint8), connectivity=4
        )
        b = stats[1:n, :4].astype(float)
        b = b[(b[:, 2] * s >= self.min_px) & (b[:, 3] * s >= self.min_px)]
        c = np.concatenate([b[:, :2], b[:, :2] + b[:, 2:]], axis=1)
        shifted = np.clip(c + np.array([1, 0, 1, 0]), 0, [w, h, w, h])
        return (
            np.concatenate([c, shifted]),
            np.concatenate([np.full(len(c), 0.9), np.full(len(c), 0.5)]),
        )


def _scene(boxes, size=(320, 240)) -> np.ndarray:
    image = np.zeros((size[1], size[0], 3), np.uint8)
    for x, y, w, h in boxes:
        image[y : y + h, x : x + w] = 255
    return image


def _sorted(b) -> np.ndarray:
    b = np.asarray(b, float).reshape(-1, 4)
    return b[np.lexsort(b.T[::-1])]


@settings(max_examples=60, deadline=None)
@given(st.floats(1.0, 2000.0), st.floats(0.5, 800.0))
def test_tiles_cover_the_frame_with_the_stated_overlap(length, tile):
    o = np.array(tile_origins(length, tile))
    assert o[0] == 0.0
    if tile >= length:
        assert len(o) == 1
        return
    assert o[-1] + tile == pytest.approx(length)
    assert np.all(np.diff(o) <= tile * (1 - TILE_OVERLAP) + 1e-9)  # neighbours share ≥ 25 %
    assert np.all(np.diff(o) > 0)


def test_without_augmentation_it_is_the_detector():
    image = _scene([(10, 20, 30, 12), (200, 100, 40, 40), (100, 150, 3, 3)])
    det = BlobNet()
    a, b = SsdTta(det, flip=False, zoom=1.0).detect(image), det.detect(image)
    np.testing.assert_array_equal(a.boxes, b.boxes)
    np.testing.assert_array_equal(a.scores, b.scores)


def test_the_mirrored_view_maps_back_onto_the_frame():
    image = _scene([(10, 20, 30, 12), (250, 100, 41, 17)])
    tta = SsdTta(BlobNet(), flip=True, zoom=1.0)
    views = tta.views(image)
    (mirror, ms), (frame, fs) = views["mirror"], views["frame"]
    # the same blobs at the same corners (the stand-in's shifted copies mirror to the left)
    np.testing.assert_allclose(_sorted(mirror[ms == 0.9]), _sorted(frame[fs == 0.9]))
    d = tta.detect(image)
    np.testing.assert_allclose(_sorted(d.boxes), [[10, 20, 30, 12], [250, 100, 41, 17]])


@pytest.mark.parametrize("zoom", [1.5, 2.0, 3.0])
def test_tiles_find_small_boats_once_with_their_exact_boxes(zoom):
    # 5 px blobs (below the stand-in's 6 px at scale 1) and a large blob across tile edges
    truth = [(40, 30, 5, 5), (300, 200, 5, 5), (158, 118, 5, 5), (20, 100, 120, 90)]
    image = _scene(truth)
    det = BlobNet()
    assert len(det.detect(image)) == 1  # the whole frame shows only the large one
    d = SsdTta(det, flip=True, zoom=zoom).detect(image)
    np.testing.assert_allclose(_sorted(d.boxes), _sorted(truth))
    assert np.all(d.scores == 0.9)


def test_tiles_of_a_frame_wider_than_the_network():
    # 704 x 576 (regDTV9's size) letterboxed to 320 x 240: scale 0.417, blobs of 12 px vanish
    truth = [(600, 500, 12, 12), (20, 300, 12, 12), (340, 280, 12, 12)]
    image = _scene(truth, (704, 576))
    d = SsdTta(BlobNet(), flip=False, zoom=1.5).detect(image)
    np.testing.assert_allclose(_sorted(d.boxes), _sorted(truth))


def test_bad_arguments_raise():
    det = BlobNet()
    with pytest.raises(ValueError, match="zoom"):
        SsdTta(det, zoom=0.5)
    with pytest.raises(ValueError, match="zoom"):
        SsdTta(det, zoom=5.0)
    with pytest.raises(ValueError, match="zoom"):
        SsdTta(det, zoom=float("nan"))
    with pytest.raises(TypeError, match="flip"):
        SsdTta(det, flip="yes")  # pyright: ignore[reportArgumentType]
    with pytest.raises(TypeError, match="detector"):
        SsdTta(object())
