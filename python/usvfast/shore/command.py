"""`usvfast shore`: run the shore/bridge camera chain over a video or a folder of frames."""

from __future__ import annotations

import time
from dataclasses import replace
from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console

from usvfast.shore.cascade import CascadeConfig, save_cascade, train_detector
from usvfast.shore.defaults import model_kind
from usvfast.shore.mardct import load_mardct
from usvfast.shore.pipeline import DETECTORS, TRACKERS, ShoreConfig, run_shore
from usvfast.shore.sort import SortConfig, sort_config_from_options


def shore_command(
    input_path: Annotated[
        Path, typer.Argument(metavar="INPUT", help="A video file or a folder of frames")
    ],
    out: Annotated[Path, typer.Option("--out", help="Output folder")],
    detector: Annotated[
        str,
        typer.Option(
            help=f"Detector: {', '.join(DETECTORS)} (auto: a fine-tuned SSD, else a trained "
            "CNN, else the zero-shot COCO SSD when the pretrained extra is installed, else bayes)"
        ),
    ] = "auto",
    model: Annotated[
        Path | None,
        typer.Option(
            help="Cascade XML (--detector cascade), CNN .onnx/.pt (--detector cnn; default "
            "the model shore-train wrote, or $USVFAST_SHORE_MODEL) or SSD .onnx (--detector "
            "ssd; default the model shore-train --detector ssd wrote, or "
            "$USVFAST_SHORE_SSD_MODEL, else the zero-shot COCO SSD); with auto, the kind "
            "named by the model's card"
        ),
    ] = None,
    reflection_filter: Annotated[
        bool, typer.Option(help="Drop boxes with few ORB keypoints (reflections)")
    ] = False,
    wake_model: Annotated[
        Path | None, typer.Option(help="Wake-filter stage XML (shore-train --wake-filter)")
    ] = None,
    tracker: Annotated[str, typer.Option(help=f"Tracker: {', '.join(TRACKERS)}")] = "sort",
    sort_high_score: Annotated[
        float,
        typer.Option(
            help="SORT two-stage association (ByteTrack): detection score from which a box is "
            "associated first and may start a track (0: one stage)"
        ),
    ] = SortConfig.high_score,
    sort_low_score: Annotated[
        float,
        typer.Option(
            help="SORT two-stage association: least score of a second-stage box "
            "(at most --sort-high-score; lower scores are dropped)"
        ),
    ] = SortConfig.low_score,
    horizon_filter: Annotated[
        bool, typer.Option(help="Drop detections well above the horizon line")
    ] = True,
    ssd_backend: Annotated[
        str,
        typer.Option(
            help="SSD inference: auto (OpenVINO when the openvino extra is installed, else "
            "OpenCV DNN), opencv or openvino"
        ),
    ] = "auto",
    ssd_precision: Annotated[
        str,
        typer.Option(
            help="SSD on OpenVINO: f32 (OpenCV DNN's scores) or bf16 (about twice as fast on "
            "CPUs with bfloat16; scores move by up to ~0.2, see the README)"
        ),
    ] = "f32",
    video: Annotated[bool, typer.Option(help="Write the annotated video")] = True,
    max_frames: Annotated[int, typer.Option(help="Stop after this many frames (0: all)")] = 0,
    progress: Annotated[bool, typer.Option(help="Show a progress bar")] = True,
) -> None:
    """Detect and track vessels in shore or bridge camera footage; write tracks.txt and
    detections.txt (MOTChallenge), an annotated video and summary.json into OUT."""
    try:
        sort = sort_config_from_options(sort_high_score, sort_low_score)
        kind = detector
        if detector == "auto" and model is not None:
            kind = model_kind(model)
        config = ShoreConfig(
            detector=detector,  # pyright: ignore[reportArgumentType]  # (ShoreConfig checks it)
            tracker=tracker,  # pyright: ignore[reportArgumentType]
            horizon_filter=horizon_filter,
            cascade_model=model if kind == "cascade" else None,
            cnn_model=model if kind in ("cnn", "fused") else None,
            ssd_model=model if kind == "ssd" else None,
            ssd_backend=ssd_backend,
            ssd_precision=ssd_precision,
            reflection_filter=reflection_filter,
            wake_model=wake_model,
            sort=sort,
        )
        s = run_shore(
            input_path, out, config, video=video, progress=progress, max_frames=max_frames
        )
    except ValueError as exc:
        raise typer.BadParameter(str(exc)) from exc
    console = Console()
    console.print(f"detector: {s.detector}, {s.detector_choice}", markup=False, highlight=False)
    console.print(
        f"{s.frames} frames ({s.undecoded_frames} undecoded) at {s.processing_fps:.1f} FPS; "
        f"{s.detections} detections ({s.detections_raw} before the horizon filter), "
        f"{s.tracks} tracks; outputs in {out}"
    )
    if s.undecoded_frames:
        console.print(
            f"[yellow]{s.undecoded_frames} frame(s) could not be decoded "
            f"(damaged or truncated input): processed up to the damage[/yellow]"
        )


def shore_train_command(
    annotations: Annotated[
        Path, typer.Argument(help="Folder of NAME_FRAME.png + NAME_FRAME.txt (boat X Y W H)")
    ],
    out: Annotated[
        Path | None,
        typer.Option(
            "--out",
            help="Cascade: the XML file to write. CNN, SSD: the model folder (default: the "
            "user model folder `usvfast shore` looks in)",
        ),
    ] = None,
    detector: Annotated[
        str | None,
        typer.Option(
            help="What to train: cnn, ssd (fine-tune the COCO SSD; needs the pretrained extra) "
            "or cascade (default: cascade for --out *.xml, else cnn)"
        ),
    ] = None,
    max_stages: Annotated[int, typer.Option(help="Cascade: most stages (the last on wakes)")] = 14,
    steps: Annotated[
        int | None, typer.Option(help="CNN, SSD: training steps (default: CNN 900, SSD 600)")
    ] = None,
    views: Annotated[
        int | None,
        typer.Option(help="SSD: augmented views run once through the frozen stem (default 1200)"),
    ] = None,
    wake_filter: Annotated[
        bool, typer.Option(help="CNN: also train the wake-filter stage (wake-filter.xml)")
    ] = False,
    seed: Annotated[int, typer.Option(help="Seed of the training draws")] = 0,
    hard_negatives: Annotated[
        bool,
        typer.Option(
            help="CNN: a second round on the first model's false alarms (kept as "
            "shore-cnn-round1), its confidence threshold chosen on each video's last frames"
        ),
    ] = False,
) -> None:
    """Train a boat detector on annotated frames: the CNN (HarbourNet, ONNX + TorchScript +
    model card), the SSD (the COCO SSD-MobileNetV2 fine-tuned by
    :mod:`usvfast.shore.ssd_train`: shore-ssd.onnx + card, threshold picked on the training
    videos) — both written to the model folder where `usvfast shore` finds them by default —
    or the Haar cascade (60 × 30 window, OpenCV XML loadable by `cv2.CascadeClassifier` and
    `usvfast shore --detector cascade`)."""
    console = Console()
    if detector is None:
        detector = "cascade" if out is not None and out.suffix == ".xml" else "cnn"
    try:
        if detector != "ssd" and views is not None:
            raise ValueError("views: only for --detector ssd")
        if detector == "ssd":
            _train_ssd(annotations, out, steps, views, seed, hard_negatives, wake_filter, console)
            return
        if detector == "cnn":
            from usvfast.shore.cnn import CnnDetector, user_model_dir
            from usvfast.shore.cnn_train import CnnTrainConfig, train_and_export
            from usvfast.shore.filters import WakeFilter

            folder = out or user_model_dir()
            cfg = CnnTrainConfig(seed=seed, steps=900 if steps is None else steps)
            first = "shore-cnn-round1" if hard_negatives else "shore-cnn"
            card = train_and_export(annotations, folder, cfg, name=first, log=console.print)
            if hard_negatives:
                from usvfast.shore.cnn_mining import train_hard_negative_round

                card = train_hard_negative_round(
                    annotations,
                    Path(folder) / f"{first}.onnx",
                    folder,
                    replace(cfg, hard_negative=0.35),
                    name="shore-cnn",
                    log=console.print,
                )
            console.print(
                f"CNN trained on {', '.join(card['videos'])} in {card['train_seconds']:.1f} s; "
                f"wrote {folder}"
            )
            if wake_filter:
                frames = [f for v in load_mardct(annotations).values() for f in v]
                det = CnnDetector(Path(folder) / "shore-cnn.onnx")
                WakeFilter.train(frames, det.detect, seed=seed).save(
                    Path(folder) / "wake-filter.xml"
                )
                console.print(f"wrote {Path(folder) / 'wake-filter.xml'}")
            return
        if detector != "cascade":
            raise ValueError(f"detector: expected 'cnn', 'ssd' or 'cascade', got {detector!r}")
        if out is None:
            raise ValueError("out: the cascade needs --out FILE.xml")
        frames = [f for v in load_mardct(annotations).values() for f in v]
        t0 = time.perf_counter()
        cascade, report = train_detector(frames, CascadeConfig(max_stages=max_stages, seed=seed))
    except ValueError as exc:
        raise typer.BadParameter(str(exc)) from exc
    save_cascade(cascade, out)
    console.print(
        f"{len(report['stages'])} stages from {report['positives']} positive windows in "
        f"{time.perf_counter() - t0:.1f} s; wrote {out}"
    )


def _train_ssd(
    annotations: Path,
    out: Path | None,
    steps: int | None,
    views: int | None,
    seed: int,
    hard_negatives: bool,
    wake_filter: bool,
    console: Console,
) -> None:
    """`shore-train --detector ssd`: :func:`usvfast.shore.ssd_train.train_and_export` into
    `out` (default the user model folder) as shore-ssd.onnx + shore-ssd.json."""
    from usvfast._extras import require
    from usvfast.shore.cnn import user_model_dir
    from usvfast.shore.defaults import SSD_MODEL_FILE
    from usvfast.shore.ssd_train import MODEL_NAME, SsdTrainConfig, train_and_export

    if hard_negatives:
        raise ValueError("hard_negatives: only for --detector cnn")
    if wake_filter:
        raise ValueError("wake_filter: only for --detector cnn")
    if out is not None and out.suffix in (".xml", ".onnx"):
        raise ValueError(f"out: the SSD is written into a model folder, got the file name {out}")
    base = SsdTrainConfig()
    cfg = SsdTrainConfig(
        seed=seed,
        steps=base.steps if steps is None else steps,
        views=base.views if views is None else views,
    )
    load_mardct(annotations)  # bad annotations fail before torch is imported
    for module in ("torch", "onnx"):
        require(module, "pretrained", "fine-tuning the SSD")
    folder = out or user_model_dir()
    card = train_and_export(annotations, folder, cfg, name=MODEL_NAME, log=console.print)
    console.print(
        f"SSD fine-tuned on {', '.join(card['videos'])} in {card['train_seconds']:.1f} s "
        f"(confidence threshold {card['conf_threshold']:g}, picked on those videos); "
        f"wrote {Path(folder) / SSD_MODEL_FILE}",
        markup=False,
        highlight=False,
    )
