"""Camera benchmarks, ours vs peers on the same input in one process.

* NMS of 10,000 candidate boxes: usvfast (Rust) vs a numpy greedy NMS and cv2.dnn.NMSBoxes.
* Georeferencing + covariance of 10,000 detections in one call: the Rust core vs a numpy
  implementation of the same maths; plus the whole calibrated call (OpenCV undistortion).
* YOLO inference per frame at 640x640 on the CPU for the test network (when torch is installed).

Run: python benches/bench_camera.py [--repeat N]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import cv2
import numpy as np

from usvfast import _core
from usvfast.camera import mount_rotation, nms
from usvfast.camera.calibration import CameraModel

from timing import best_of


def numpy_nms(boxes, scores, thr):
    order = np.argsort(-scores, kind="stable")
    x1, y1, x2, y2 = boxes.T
    area = (x2 - x1) * (y2 - y1)
    keep = []
    while order.size:
        i = order[0]
        keep.append(i)
        rest = order[1:]
        w = np.clip(np.minimum(x2[i], x2[rest]) - np.maximum(x1[i], x1[rest]), 0, None)
        h = np.clip(np.minimum(y2[i], y2[rest]) - np.maximum(y1[i], y1[rest]), 0, None)
        inter = w * h
        iou = inter / (area[i] + area[rest] - inter)
        order = rest[iou <= thr]
    return np.array(keep)


def rot_x(a):
    c, s = np.cos(a), np.sin(a)
    z, o = np.zeros_like(a), np.ones_like(a)
    return np.stack(
        [np.stack([o, z, z], -1), np.stack([z, c, -s], -1), np.stack([z, s, c], -1)], -2
    )


def rot_y(a):
    c, s = np.cos(a), np.sin(a)
    z, o = np.zeros_like(a), np.ones_like(a)
    return np.stack(
        [np.stack([c, z, s], -1), np.stack([z, o, z], -1), np.stack([-s, z, c], -1)], -2
    )


def d_rot_x(a):
    c, s = np.cos(a), np.sin(a)
    z = np.zeros_like(a)
    return np.stack(
        [np.stack([z, z, z], -1), np.stack([z, -s, -c], -1), np.stack([z, c, -s], -1)], -2
    )


def d_rot_y(a):
    c, s = np.cos(a), np.sin(a)
    z = np.zeros_like(a)
    return np.stack(
        [np.stack([-s, z, c], -1), np.stack([z, z, z], -1), np.stack([-c, z, -s], -1)], -2
    )


def numpy_georef(norm, jac, roll, pitch, h, r_bc, t_b, sig_px, sig_att, sig_h):
    """The same ray-plane intersection and Jacobian as rust/src/georef.rs, vectorised."""
    rx, ry = rot_x(roll), rot_y(pitch)
    r_lb = ry @ rx
    d_c = np.concatenate([norm, np.ones((len(norm), 1))], axis=1)
    d_b = d_c @ r_bc.T
    d = np.einsum("nij,nj->ni", r_lb, d_b)
    ok = d[:, 2] > 0
    c = np.einsum("nij,j->ni", r_lb, t_b)
    s = h / d[:, 2]
    p = c[:, :2] + s[:, None] * d[:, :2]
    g = np.zeros((len(d), 2, 3))
    g[:, 0, 0] = s
    g[:, 1, 1] = s
    g[:, 0, 2] = -s * d[:, 0] / d[:, 2]
    g[:, 1, 2] = -s * d[:, 1] / d[:, 2]
    r_lc = r_lb @ r_bc
    j_px = g @ r_lc[:, :, :2] @ jac
    dr_r = ry @ d_rot_x(roll)
    dr_p = d_rot_y(pitch) @ rx
    j_r = np.einsum("nij,j->ni", dr_r, t_b)[:, :2] + np.einsum(
        "nij,nj->ni", g, np.einsum("nij,nj->ni", dr_r, d_b)
    )
    j_p = np.einsum("nij,j->ni", dr_p, t_b)[:, :2] + np.einsum(
        "nij,nj->ni", g, np.einsum("nij,nj->ni", dr_p, d_b)
    )
    j_h = d[:, :2] / d[:, 2:3]
    cov = (
        j_px @ np.diag(np.square(sig_px)) @ j_px.transpose(0, 2, 1)
        + sig_att[0] ** 2 * np.einsum("ni,nj->nij", j_r, j_r)
        + sig_att[1] ** 2 * np.einsum("ni,nj->nij", j_p, j_p)
        + sig_h**2 * np.einsum("ni,nj->nij", j_h, j_h)
    )
    p[~ok] = np.nan
    cov[~ok] = np.nan
    return p, cov


def bench_nms(repeat):
    rng = np.random.default_rng(0)
    n = 10_000
    xy = rng.uniform(0, [1920, 1080], (n, 2))
    wh = rng.uniform(10, 100, (n, 2))
    boxes = np.hstack([xy, xy + wh])
    scores = rng.uniform(0, 1, n)
    t_ours, ours = best_of(lambda: nms(boxes, scores, 0.45), repeat)
    t_np, ref = best_of(lambda: numpy_nms(boxes, scores, 0.45), repeat)
    assert np.array_equal(ours, ref), "NMS differs from the numpy reference"
    print(
        f"NMS 10,000 boxes: usvfast {t_ours * 1e3:.2f} ms, numpy {t_np * 1e3:.2f} ms, "
        f"ratio {t_np / t_ours:.1f}x  (kept {len(ours)})"
    )
    xywh = [[float(b[0]), float(b[1]), float(b[2] - b[0]), float(b[3] - b[1])] for b in boxes]
    sc = [float(s) for s in scores]
    t_cv, cvk = best_of(lambda: cv2.dnn.NMSBoxes(xywh, sc, 0.0, 0.45), repeat)
    same = set(np.asarray(cvk).ravel().tolist()) == set(ours.tolist())
    print(
        f"  cv2.dnn.NMSBoxes {t_cv * 1e3:.2f} ms, ratio {t_cv / t_ours:.1f}x "
        f"(same kept set: {same})"
    )


def bench_georef(repeat):
    rng = np.random.default_rng(1)
    n = 10_000
    k = np.array([[900.0, 0, 640], [0, 900.0, 360], [0, 0, 1]])
    cam = CameraModel(k, np.array([-0.2, 0.05, 0.001, -0.001, 0.0]), (1280, 720))
    px = np.stack([rng.uniform(0, 1280, n), rng.uniform(380, 720, n)], axis=1)
    norm, jac = cam.normalized(px)
    roll = rng.uniform(-0.05, 0.05, n)
    pitch = rng.uniform(-0.05, 0.05, n)
    h = np.full(n, 2.5)
    r_bc = mount_rotation((0.0, -5.0, 0.0))
    t_b = np.array([1.0, 0.0, -2.0])
    sig = dict(sigma_px=(1.0, 1.0), sigma_roll_pitch=(0.005, 0.005), sigma_height=0.05)

    def ours():
        return _core.georeference_rays(norm, jac, roll, pitch, h, r_bc, tuple(t_b), **sig)

    def ref():
        return numpy_georef(norm, jac, roll, pitch, h, r_bc, t_b, (1.0, 1.0), (0.005, 0.005), 0.05)

    t_ours, (p, c, _) = best_of(ours, repeat)
    t_np, (pr, cr) = best_of(ref, repeat)
    np.testing.assert_allclose(p, pr, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(c, cr, rtol=1e-7, atol=1e-12)
    print(
        f"Georeference + covariance, 10,000 detections: usvfast {t_ours * 1e3:.2f} ms, "
        f"numpy {t_np * 1e3:.2f} ms, ratio {t_np / t_ours:.1f}x"
    )
    from usvfast.camera import georeference

    t_full, _ = best_of(
        lambda: georeference(
            px,
            cam,
            height=2.5,
            mount_rotation=r_bc,
            mount_position=t_b,
            roll=roll,
            pitch=pitch,
            pixel_sigma=1.0,
            attitude_sigma=0.005,
            height_sigma=0.05,
        ),
        repeat,
    )
    print(f"  whole calibrated call incl. OpenCV undistortion + Jacobian: {t_full * 1e3:.2f} ms")


def bench_yolo(repeat):
    try:
        import torch
    except ImportError:
        print("YOLO: torch not installed (.ci/install-torch.sh), skipped")
        return
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
    from yolo_nets import KnownBoxesYolo

    from usvfast.camera.yolo import YoloDetector

    torch.set_num_threads(1)
    det = YoloDetector(KnownBoxesYolo(torch.zeros(1, 1, 7)), device="cpu")
    frame = np.random.default_rng(0).integers(0, 255, (720, 1280, 3), dtype=np.uint8)
    det([frame])
    t, _ = best_of(lambda: det([frame]), repeat)
    x = torch.zeros(1, 3, 640, 640)
    with torch.inference_mode():
        t_net, _ = best_of(lambda: det.model(x), repeat)
    print(
        f"YOLO test network, CPU 1 thread, 640x640: {t * 1e3:.1f} ms per frame end to end "
        f"(letterbox + net + decode + NMS), network alone {t_net * 1e3:.1f} ms"
    )


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=5)
    a = ap.parse_args()
    bench_nms(a.repeat)
    bench_georef(a.repeat)
    bench_yolo(a.repeat)


if __name__ == "__main__":
    main()
