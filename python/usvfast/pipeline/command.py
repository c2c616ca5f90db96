"""`usvfast run CONFIG --out DIR [--truth truth.csv]` and `usvfast demo`: the pipeline from the
shell, with a progress bar and a final summary table (tracks, metrics when a truth is given,
time per stage, real-time factor)."""

from __future__ import annotations

import json
from importlib import resources
from pathlib import Path
from typing import Annotated, Any

import typer
from rich.console import Console
from rich.markup import escape
from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn
from rich.table import Table

__all__ = ["bundled_recording", "demo_command", "run_command", "run_pipeline"]

#: The bundled recording's seed and length (usvfast simulate --seed 7 --duration 60).
DEMO_SEED = 7
DEMO_DURATION = 60.0


def _parse_set(items: list[str] | None) -> dict[str, Any]:
    import tomllib

    out: dict[str, Any] = {}
    for item in items or []:
        key, sep, value = item.partition("=")
        if not sep or not key:
            raise typer.BadParameter(f"--set: expected key=value, got {item!r}")
        try:
            out[key.strip()] = tomllib.loads(f"v = {value.strip()}")["v"]
        except tomllib.TOMLDecodeError:
            out[key.strip()] = value.strip()
    return out


def summary_tables(summary: dict[str, Any]) -> list[Table]:
    """The run's summary as rich tables: overview, time per stage, metrics (when given)."""
    over = Table(title=f"usvfast run: {summary['recording']}")
    over.add_column("quantity")
    over.add_column("value", justify="right")
    det = summary["detections"]
    rows = [
        ("recording span", f"{summary['duration_s']:.1f} s"),
        ("wall time", f"{summary['wall_s']:.2f} s"),
        ("real-time factor", f"{summary['real_time_factor']:.1f}x"),
        ("tracker scans", str(summary["scans"])),
        ("detections (lidar / camera)", f"{det['lidar']} / {det['camera']}"),
        ("confirmed tracks", str(summary["tracks"])),
        ("damaged messages (skipped)", str(summary["damaged_messages"])),
        ("tracker", summary["tracker_backend"]),
    ]
    if summary.get("detector_runtime"):
        rows.append(("camera network on", summary["detector_runtime"]))
    cal = summary.get("heading_calibration")
    if cal is not None:
        found = (
            f"{cal['offset_deg']:+.2f} deg (over {cal['baseline_m']:.0f} m)"
            if cal["observable"]
            else f"not observable ({cal['baseline_m']:.0f} m travelled)"
        )
        rows.append(("heading correction from the LiDAR", found))
    for k, v in rows:
        over.add_row(k, v)
    title = "time per stage"
    if "camera.wait" in summary["stages"]:
        title += (
            " (camera.detector ran on a worker thread alongside the others; camera.wait: "
            "the main thread waiting for it)"
        )
    stages = Table(title=title)
    for col in ("stage", "calls", "ms / call", "total s", "share"):
        stages.add_column(col, justify="left" if col == "stage" else "right")
    total = sum(v["seconds"] for v in summary["stages"].values()) or 1.0
    for name, v in summary["stages"].items():
        stages.add_row(
            name,
            str(v["calls"]),
            f"{v['ms_per_call']:.2f}",
            f"{v['seconds']:.3f}",
            f"{100 * v['seconds'] / total:.0f} %",
        )
    tables = [over, stages]
    metrics = summary.get("metrics") or {}
    flat = {k: v for k, v in metrics.items() if isinstance(v, int | float | str | bool)}
    if flat:
        mt = Table(title="metrics (against the truth)")
        mt.add_column("metric")
        mt.add_column("value", justify="right")
        for k, v in flat.items():
            mt.add_row(k, f"{v:.4g}" if isinstance(v, float) else str(v))
        tables.append(mt)
    return tables


def run_pipeline(
    config: Path,
    out: Path,
    *,
    truth: Path | None = None,
    scene: Path | None = None,
    overrides: dict[str, Any] | None = None,
    console: Console | None = None,
) -> dict[str, Any]:
    """Run a config with a progress bar, print the summary tables; returns the summary."""
    from usvfast.pipeline import Pipeline, load_config

    console = console or Console()
    cfg = load_config(config, overrides)
    pipe = Pipeline(cfg)
    with Progress(
        TextColumn("[bold]{task.description}"),
        BarColumn(),
        TextColumn("{task.completed:.0f}/{task.total:.0f} s"),
        TimeRemainingColumn(),
        console=console,
        transient=True,
    ) as bar:
        task = bar.add_task(f"replaying {cfg.recording.name}", total=1.0)

        def progress(t: float, span: float) -> None:
            bar.update(task, completed=max(0.0, t), total=max(span, 1e-9))

        for _ in pipe.run(out=out, truth=truth, scene=scene, progress=progress):
            pass
    for table in summary_tables(pipe.summary):
        console.print(table)
    console.print(f"wrote {escape(str(out))}/ (tracks.csv, summary.json, ...)", soft_wrap=True)
    return pipe.summary


def run_command(
    config: Annotated[Path, typer.Argument(help="Pipeline config (TOML or YAML).")],
    out: Annotated[Path, typer.Option(help="Output directory.")] = Path("out/run"),
    truth: Annotated[
        Path | None, typer.Option(help="Ground truth CSV (time,object_id,kind,north,east,...).")
    ] = None,
    scene: Annotated[Path | None, typer.Option(help="scene.json of a simulated recording.")] = None,
    backend: Annotated[
        str | None, typer.Option(help="Tracker backend override: native or stonesoup.")
    ] = None,
    set_: Annotated[
        list[str] | None,
        typer.Option("--set", help="Override a config key, e.g. --set tracker.prob_detect=0.9."),
    ] = None,
) -> None:
    """Run the detection and tracking pipeline over a recording: tracks, detections, nav,
    innovations, summary (and metrics and pictures with --truth) into --out."""
    from usvfast.pipeline import ConfigError
    from usvfast.pipeline.pose import NavigationError

    overrides = _parse_set(set_)
    if backend is not None:
        overrides["tracker.backend"] = backend
    try:
        run_pipeline(config, out, truth=truth, scene=scene, overrides=overrides)
    except (ConfigError, NavigationError) as exc:
        Console(stderr=True).print(f"[red]error:[/red] {escape(str(exc))}", soft_wrap=True)
        raise typer.Exit(2) from exc


def bundled_recording() -> Path | None:
    """recording.toml of the bundled harbour recording (usvfast/data/harbour/), or None."""
    folder = resources.files("usvfast") / "data" / "harbour"
    path = Path(str(folder)) / "recording.toml"
    return path if path.is_file() else None


def demo_command(
    out: Annotated[Path, typer.Option(help="Output directory.")] = Path("out/demo"),
) -> None:
    """The main job: the bundled harbour recording (LiDAR packets, camera, GNSS, IMU) through
    the whole pipeline; prints the metrics table and writes tracks, plots and the animation."""
    console = Console()
    config = bundled_recording()
    if config is None:
        # No bundle in this install: simulate the same recording (seed 7, 60 s) first.
        from usvfast.sim.recording import SimulationOptions, simulate

        rec = out / "recording"
        if not (rec / "recording.toml").exists():
            console.print(f"simulating the harbour recording into {escape(str(rec))}")
            simulate(rec, SimulationOptions(seed=DEMO_SEED, duration=DEMO_DURATION))
        config = rec / "recording.toml"
    folder = config.parent
    truth = folder / "truth.csv"
    scene = folder / "scene.json"
    console.print(f"recording: {escape(str(config))}", soft_wrap=True)
    overrides: dict[str, Any] = {}
    try:
        from usvfast.pipeline import load_config
        from usvfast.pipeline.camera_chain import load_detector

        cfg = load_config(config)
        load_detector(cfg.detector, config.parent)
    except (ValueError, ImportError) as exc:
        console.print(
            f"[yellow]camera detector unavailable ({escape(str(exc))}): running the LiDAR "
            "chain only[/yellow]",
            soft_wrap=True,
        )
        overrides["detector.backend"] = "none"
    summary = run_pipeline(
        config,
        out,
        truth=truth if truth.exists() else None,
        scene=scene if scene.exists() else None,
        overrides=overrides,
        console=console,
    )
    (out / "demo.json").write_text(json.dumps({"config": str(config), "tracks": summary["tracks"]}))
