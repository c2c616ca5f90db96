"""Shore-camera chain speed, in the layout of Bloisi et al.'s Table V (frame size, FPS on
2 cores; their 15.5 FPS at 319×261 on 2 cores is printed as the reference).

* Detection + tracking FPS (the whole `ShoreChain.step`: day/night class, threshold +
  morphology + keypoints, horizon line, tracker) at 320×240 and 704×576, for the SIFT
  keypoints (closest to the paper's STAR) and FAST, with the SORT-like tracker.
* The SORT step's Kalman part for 20 tracks: usvfast's stacked Rust predict/update vs
  filterpy's KalmanFilter per track, same numbers (ratio printed).

Frames: MarDCT's regDTV9 frames resized to each size when ../shared/data is present
(USVFAST_SHARED_DATA), else synthetic sea-and-sky frames with moving dark hulls.

* With `--cascade boat.xml` (from `usvfast shore-train`), the cascade detector too.
* Tracking alone (per frame, 5 boats, colour histograms included) for the SORT-like and the
  particle tracker, and the chain's FPS with each tracker.
* One local-tier step of the particle filter (propagate, proposals, weights, SIR, KClusterize):
  usvfast's Rust vs the plain numpy version of tests/particle_reference.py, same numbers.
* With `--cnn shore-cnn.onnx` (from `usvfast shore-train --detector cnn`), the CNN detector run
  by OpenCV DNN at the model's small input (the frame is letterboxed once), alone and with
  the reflection filter; without `--cnn`, an untrained network of the same architecture and
  input size is timed (same cost per frame; it finds nothing, so NMS and tracking are idle).
  Per-stage milliseconds (detect / horizon / track) are printed for each run.
* The training-free contrast detector (`usvfast.shore.contrast`) and the fused CNN +
  contrast score (`usvfast.shore.fused`, on the `--cnn` model or the untrained one).
* The temporal change detector (`usvfast.shore.change`, online: every frame registered to
  the previous one, ORB + ECC, and compared with the median of the 4 previous ones), in the
  chain; beside it, OpenCV's MOG2 background subtractor alone on the same frames (no
  registration, no boxes: the library's cheapest per-pixel background, for scale).

* The COCO-pretrained SSD-MobileNetV2 (`usvfast.shore.pretrained`, OpenCV DNN): zero-shot
  at the COCO graph's 300 × 300 input (exported to ONNX in a temporary folder; needs the
  `pretrained` extra and torch), and with `--ssd shore-ssd.onnx` (from
  `python -m usvfast.shore.ssd_train`) the fine-tuned model at its 320 × 240 input, alone and
  with the test-time views of `usvfast.shore.ssd_tta` (mirror; tiles of the frame enlarged
  1.5 ×; both); each timed as detect + horizon filter + SORT-like tracker per frame.
* With `--ssd`, the fine-tuned model on each run-time of `--ssd-runtimes` (default: OpenCV
  DNN, OpenVINO float32 and bfloat16 when the `openvino` extra is installed; `openvino-int8`
  with `--ssd-int8 MODEL-int8.onnx` from `python -m usvfast.shore.ssd_quant`), on the same
  frames in the same process, runs interleaved, best of `--ssd-runs`: the network alone (the
  letterboxed frame in, scores out), the whole detect + horizon + SORT as FPS, each run-time's
  speed-up over OpenCV DNN, and its largest score difference from OpenCV DNN; and the
  letterbox resize alone (what detect adds before the network).

Run: python benches/bench_shore.py [--frames N] [--repeat R] [--cascade boat.xml]
    [--cnn MODEL.onnx] [--ssd MODEL.onnx] [--ssd-int8 MODEL-int8.onnx]
    [--ssd-runtimes opencv openvino ...] [--ssd-runs N] [--only contrast fused change ssd]
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np
from filterpy.kalman import KalmanFilter

from usvfast import _core
from usvfast.kalman import predict_states, update_states
from usvfast.shore import ShoreChain, ShoreConfig
from usvfast.shore.bayes import BayesDetectorConfig
from usvfast.shore.boxes import Detections
from usvfast.shore.particle import ParticleTracker
from usvfast.shore.sort import SortTracker

from timing import best_of

PAPER_FPS = 15.5  # Table V, 319×261, 2 cores


def frames_at(size: tuple[int, int], n: int) -> list[np.ndarray]:
    """n BGR frames of size (w, h): MarDCT regDTV9 frames if present, else synthetic."""
    root = Path(os.environ.get("USVFAST_SHARED_DATA", "../shared/data"))
    files = sorted((root / "mardct" / "training" / "annotations").glob("regDTV9_*.png"))
    if files:
        return [cv2.resize(cv2.imread(str(files[i % len(files)])), size) for i in range(n)]
    w, h = size
    out = []
    for k in range(n):
        img = np.full((h, w, 3), (190, 170, 150), np.uint8)
        img[h // 2 :] = (110, 80, 50)
        x = (20 + 3 * k) % (w - 60)
        cv2.rectangle(img, (x, h // 2 - 12), (x + 50, h // 2 + 6), (10, 10, 10), -1)
        out.append(img)
    return out


def chain_fps(
    frames: list[np.ndarray],
    keypoints: str,
    model: Path | None = None,
    config: ShoreConfig | None = None,
    tracker: str = "sort",
) -> tuple[float, dict[str, float]]:
    """(frames per second of ShoreChain.step, milliseconds per frame of each stage)."""
    cfg = ShoreConfig(
        detector="bayes",
        tracker=tracker,
        bayes=replace(BayesDetectorConfig(), keypoints=keypoints),
    )
    if model is not None:
        cfg = replace(cfg, detector="cascade", cascade_model=model)
    chain = ShoreChain(config or cfg)
    chain.step(frames[0])  # warm-up
    chain.seconds.clear()
    t0 = time.perf_counter()
    for f in frames:
        chain.step(f)
    stages = {k: 1e3 * v / len(frames) for k, v in chain.seconds.items()}
    return len(frames) / (time.perf_counter() - t0), stages


def ssd_fps(
    frames: list[np.ndarray], model: Path, tta: tuple[bool, float] | None = None, det=None
) -> tuple[float, dict[str, float]]:
    """(frames per second, ms per frame of each stage) of the SSD run by OpenCV DNN (or the
    SsdDetector `det`; with `tta` (flip, zoom): the test-time views of usvfast.shore.ssd_tta),
    the horizon filter and the SORT-like tracker, frame by frame."""
    from usvfast.shore.horizon import HorizonConfig, detect_horizon, horizon_keep
    from usvfast.shore.pretrained import SsdDetector
    from usvfast.shore.ssd_tta import SsdTta

    det = det or SsdDetector(model)
    if tta is not None:
        det = SsdTta(det, flip=tta[0], zoom=tta[1])
    hcfg = HorizonConfig()
    tracker = SortTracker()
    det.detect(frames[0])  # warm-up
    sec = {"detect": 0.0, "horizon": 0.0, "track": 0.0}
    t0 = time.perf_counter()
    for f in frames:
        t = time.perf_counter()
        d = det.detect(f)
        t1 = time.perf_counter()
        d = d.subset(horizon_keep(d, detect_horizon(f, config=hcfg), f.shape[0], hcfg))
        t2 = time.perf_counter()
        tracker.step(f, d)
        t3 = time.perf_counter()
        sec["detect"] += t1 - t
        sec["horizon"] += t2 - t1
        sec["track"] += t3 - t2
    fps = len(frames) / (time.perf_counter() - t0)
    return fps, {k: 1e3 * v / len(frames) for k, v in sec.items()}


def ssd_runtimes(
    frames: list[np.ndarray], models: dict[str, Path], runs: int
) -> dict[str, tuple[float, float, float]]:
    """Per run-time name of usvfast.shore.ssd_eval.RUNTIMES (`models`: its .onnx file):
    (ms per frame of the network alone, FPS of detect + horizon + SORT, largest |score|
    difference from OpenCV DNN over every anchor of every frame); runs interleaved across
    run-times, best of `runs`. Run-times whose package is missing are left out, with a note."""
    from usvfast._extras import MissingExtraError
    from usvfast.shore.pretrained import SsdDetector, letterboxed
    from usvfast.shore.ssd_eval import runtime_options

    dets = {}
    for name, model in models.items():
        backend, precision, _ = runtime_options(name)
        try:
            dets[name] = SsdDetector(model, backend=backend, precision=precision)
        except MissingExtraError as exc:
            print(f"SSD on {name} not timed: {exc}")
    ref = dets["opencv"]
    small = [letterboxed(f, ref.input_size, ref.letterbox)[0] for f in frames]
    t, _ = best_of(lambda: [letterboxed(f, ref.input_size, ref.letterbox) for f in frames], runs)
    print(f"{'':>9} letterbox to the network's input alone: {1e3 * t / len(frames):.2f} ms/frame")
    nets = {k: d.runtime for k, d in dets.items() if d.runtime is not None}
    scores = [nets["opencv"](x)[:, 4:] for x in small]
    best = {k: [np.inf, 0.0, 0.0] for k in dets}
    for name, net in nets.items():
        diff = max(np.abs(net(x)[:, 4:] - s).max() for x, s in zip(small, scores, strict=True))
        best[name][2] = float(diff)
    for _ in range(runs):
        for name, det in dets.items():
            t, _ = best_of(lambda net=nets[name]: [net(x) for x in small], 1)
            best[name][0] = min(best[name][0], 1e3 * t / len(small))
            fps, _ = ssd_fps(frames, models[name], det=det)
            best[name][1] = max(best[name][1], fps)
    return {k: (v[0], v[1], v[2]) for k, v in best.items()}


def coco_ssd(folder: Path) -> Path | None:
    """The zero-shot COCO SSD exported to ONNX (None without the weights or torch)."""
    try:
        from usvfast.shore.pretrained import coco_network, export_onnx

        return export_onnx(coco_network(), folder / "coco-ssd.onnx", (300, 300))
    except (ImportError, ValueError) as exc:
        print(f"COCO SSD not timed: {exc}")
        return None


def mog2_fps(frames: list[np.ndarray]) -> float:
    """Frames per second of OpenCV's MOG2 subtractor's `apply` alone (foreground mask only)."""
    sub = cv2.createBackgroundSubtractorMOG2(history=4, detectShadows=False)
    sub.apply(frames[0])
    t0 = time.perf_counter()
    for f in frames:
        sub.apply(f)
    return len(frames) / (time.perf_counter() - t0)


def untrained_cnn(folder: Path) -> Path:
    """An untrained one-class HarbourNet at the shore model's input size, as ONNX."""
    import torch

    from usvfast.camera.harbour_net import HarbourNet
    from usvfast.shore.cnn_train import CnnTrainConfig, export_model, model_card

    cfg = CnnTrainConfig()
    torch.manual_seed(0)
    net = HarbourNet(1, cfg.input_size, cfg.width).eval()
    export_model(net, folder, model_card(cfg, [], 0.0, net), name="untrained")
    return folder / "untrained.onnx"


def kalman_step_compare(k: int, repeat: int) -> None:
    rng = np.random.default_rng(0)
    f = np.eye(7)
    f[0, 4] = f[1, 5] = f[2, 6] = 1.0
    q = np.diag([1, 1, 1, 1, 1e-2, 1e-2, 1e-4])
    h, r = np.eye(4, 7), np.diag([1.0, 1.0, 10.0, 10.0])
    x = rng.normal(100, 10, (k, 7))
    p = np.repeat(np.diag([10, 10, 10, 10, 1e4, 1e4, 1e4])[None], k, axis=0)
    z = rng.normal(100, 10, (k, 4))

    def ours():
        xp, pp = predict_states(x, p, transition_matrix=f, process_noise=q)
        return update_states(xp, pp, z, measurement_matrix=h, measurement_noise=r)[0]

    filters = []
    for _ in range(k):
        kf = KalmanFilter(dim_x=7, dim_z=4)
        kf.F, kf.Q, kf.H, kf.R = f, q, h, r
        filters.append(kf)

    def peer():
        out = []
        for i, kf in enumerate(filters):
            kf.x, kf.P = x[i].copy(), p[i].copy()
            kf.predict()
            kf.update(z[i])
            out.append(kf.x)
        return np.array(out)

    t_ours, a = best_of(ours, repeat)
    t_peer, b = best_of(peer, repeat)
    assert np.allclose(a, b, atol=1e-9)
    print(
        f"SORT Kalman step, {k} tracks: usvfast {t_ours * 1e6:.0f} µs, filterpy "
        f"{t_peer * 1e6:.0f} µs, ratio {t_peer / t_ours:.1f}x"
    )


def boats(size: tuple[int, int], n_frames: int, k: int = 5) -> list[Detections]:
    """k boxes moving across a frame of size (w, h), n_frames frames."""
    w, h = size
    out = []
    for f in range(n_frames):
        x = (np.arange(k) * w / k + 2.0 * f) % (w - 0.15 * w)
        y = h * (0.4 + 0.1 * np.arange(k) / k)
        b = np.column_stack([x, y, np.full(k, 0.12 * w), np.full(k, 0.06 * w)])
        out.append(Detections(b, np.ones(k), np.full(k, -1)))
    return out


def tracking_ms(frames: list[np.ndarray], size: tuple[int, int]) -> dict[str, float]:
    """Milliseconds per frame of each tracker alone (histograms included), 5 boats."""
    dets = boats(size, len(frames))
    out = {}
    for name, make in (("sort", SortTracker), ("particle", ParticleTracker)):
        t = make()
        t.step(frames[0], dets[0])
        t0 = time.perf_counter()
        for img, d in zip(frames, dets, strict=True):
            t.step(img, d)
        out[name] = (time.perf_counter() - t0) / len(frames) * 1e3
    return out


def local_step_compare(repeat: int) -> None:
    """One local-tier step, 5 boats × 64 particles: Rust vs the numpy reference."""
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
    import particle_reference as ref

    rng = np.random.default_rng(0)
    centres = rng.uniform(0, 300, (5, 2))
    prior = np.concatenate(
        [
            np.column_stack([c + rng.normal(0, 3, (64, 2)), rng.normal(1, 0.3, (64, 2))])
            for c in centres
        ]
    )
    obs = np.column_stack([centres + 1.0, np.full((5, 2), 3.0)])
    vel = np.ones((5, 2))
    kw = dict(count=64, dt=2.0, accel_std=0.05, vel_std=0.3, clutter=1e-9, n_out=320, delta=20.0)
    t_ours, a = best_of(lambda: _core.particle_local_step(prior, obs, vel, seed=1, **kw), repeat)
    t_peer, b = best_of(lambda: ref.local_step(prior, obs, vel, seed=1, **kw), repeat)
    assert np.allclose(a[0], b[0], atol=1e-9) and len(a[1]) == len(b[1])
    print(
        f"particle local step, 5 boats x 64 particles: usvfast {t_ours * 1e6:.0f} µs, numpy "
        f"{t_peer * 1e6:.0f} µs, ratio {t_peer / t_ours:.1f}x (same numbers)"
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--frames", type=int, default=40)
    ap.add_argument("--repeat", type=int, default=20)
    ap.add_argument(
        "--cascade", type=Path, default=None, help="Cascade XML (usvfast shore-train) to time"
    )
    ap.add_argument("--cnn", type=Path, default=None, help="CNN ONNX (shore-train) to time")
    ap.add_argument("--ssd", type=Path, default=None, help="Fine-tuned SSD ONNX (ssd_train)")
    ap.add_argument("--ssd-int8", type=Path, default=None, help="Its int8 model (ssd_quant)")
    ap.add_argument(
        "--ssd-runtimes",
        nargs="*",
        default=["opencv", "openvino", "openvino-bf16", "openvino-int8"],
        help="Run-times of the --ssd model compared (openvino-int8 needs --ssd-int8)",
    )
    ap.add_argument("--ssd-runs", type=int, default=5, help="Interleaved runs per run-time")
    ap.add_argument("--only", nargs="*", default=None, help="Time only these detector rows")
    a = ap.parse_args()
    cv2.setNumThreads(2)
    tmp = tempfile.TemporaryDirectory()
    ssd_models = {
        "ssd coco 300": (coco_ssd(Path(tmp.name)), None),
        "ssd fine-tuned": (a.ssd, None),
        "ssd ft flip": (a.ssd, (True, 1.0)),
        "ssd ft zoom1.5": (a.ssd, (False, 1.5)),
        "ssd ft flip+z1.5": (a.ssd, (True, 1.5)),
    }
    cnn = a.cnn or untrained_cnn(Path(tmp.name))
    cnn_name = "cnn onnx" if a.cnn else "cnn (untrained)"
    load = os.getloadavg()
    print(f"load average at start: {load[0]:.2f} {load[1]:.2f} {load[2]:.2f} (1, 5, 15 min)")
    print(f"{'frame size':>12} {'detector':>16} {'FPS (2 cores)':>14} {'vs paper':>9}")
    print(f"{'319x261':>12} {'paper cascade':>16} {PAPER_FPS:>14.1f} {'(paper)':>9}")
    for size in ((320, 240), (704, 576)):
        frames = frames_at(size, a.frames)
        runs = [(f"bayes {kp}", kp, None, None) for kp in ("sift", "fast")]
        runs.append(
            (
                "bayes fast+pf",
                "fast",
                None,
                ShoreConfig(
                    detector="bayes",
                    tracker="particle",
                    bayes=replace(BayesDetectorConfig(), keypoints="fast"),
                ),
            )
        )
        if a.cascade is not None:
            runs.append(("cascade", "sift", a.cascade, None))
        cnn_cfg = ShoreConfig(detector="cnn", cnn_model=cnn, tracker="sort")
        runs.append((cnn_name, "sift", None, cnn_cfg))
        runs.append((f"{cnn_name} +refl", "sift", None, replace(cnn_cfg, reflection_filter=True)))
        runs.append(("contrast", "sift", None, ShoreConfig(detector="contrast", tracker="sort")))
        runs.append(("fused", "sift", None, replace(cnn_cfg, detector="fused")))
        runs.append(("change", "sift", None, ShoreConfig(detector="change", tracker="sort")))
        if a.only:
            runs = [r for r in runs if r[0] in a.only]
        for name, kp, model, cfg in runs:
            fps, stages = chain_fps(frames, kp, model, cfg)
            ms = " ".join(f"{k} {v:.2f}" for k, v in stages.items())
            print(
                f"{size[0]}x{size[1]:<8} {name:>16} {fps:>14.1f} {fps / PAPER_FPS:>8.2f}x"
                f"   ms/frame: {ms}"
            )
        if not a.only or "ssd" in a.only:
            for name, (model, tta) in ssd_models.items():
                if model is None:
                    continue
                fps, stages = ssd_fps(frames, model, tta)
                ms = " ".join(f"{k} {v:.2f}" for k, v in stages.items())
                print(
                    f"{size[0]}x{size[1]:<8} {name:>16} {fps:>14.1f} {fps / PAPER_FPS:>8.2f}x"
                    f"   ms/frame: {ms}"
                )
        if a.ssd is not None and (not a.only or "ssd" in a.only):
            models = {r: a.ssd for r in a.ssd_runtimes if r != "openvino-int8"}
            if a.ssd_int8 is not None and "openvino-int8" in a.ssd_runtimes:
                models["openvino-int8"] = a.ssd_int8
            models = {"opencv": a.ssd, **models}
            rows = ssd_runtimes(frames, models, a.ssd_runs)
            net0, fps0, _ = rows["opencv"]
            for name, (net, fps, diff) in rows.items():
                print(
                    f"{size[0]}x{size[1]:<8} {'ssd ' + name:>20} {fps:>10.1f} FPS "
                    f"({fps / fps0:.2f}x OpenCV DNN)   network alone {net:.2f} ms "
                    f"({net0 / net:.2f}x)   max |score - OpenCV DNN| {diff:.2g}"
                )
        if not a.only or "change" in a.only:
            fps = mog2_fps(frames)
            print(f"{size[0]}x{size[1]:<8} {'opencv MOG2 alone':>16} {fps:>14.1f}")
        ms = tracking_ms(frames, size)
        print(
            f"{size[0]}x{size[1]:<8} tracking alone, 5 boats: "
            + ", ".join(f"{k} {v:.2f} ms/frame ({1e3 / v:.0f} FPS)" for k, v in ms.items())
        )
    kalman_step_compare(20, a.repeat)
    local_step_compare(a.repeat)
    load = os.getloadavg()
    print(f"load average at end: {load[0]:.2f} {load[1]:.2f} {load[2]:.2f} (1, 5, 15 min)")


if __name__ == "__main__":
    main()
