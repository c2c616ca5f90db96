"""`usvfast bearing` and `usvfast demo`: fuse camera bearings from CSV files, compare with AIS,
write the fused CSV, the RMSE table and a plot."""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Any

import numpy as np
import typer
from rich.console import Console
from rich.markup import escape
from rich.table import Table

from usvfast._angles import wrap_180_deg
from usvfast._time import unix_to_iso
from usvfast.bearing.ais import reference_bearing_deg
from usvfast.bearing.angles import unwrap_raw_deg as unwrap_deg
from usvfast.bearing.fusion import (
    PAPER_MEASUREMENT_STD_DEG,
    PAPER_NOISE_DIFF_COEFF_DEG2,
    SOURCE_NAMES,
    THERMAL,
    VISIBLE,
    BearingFusion,
    RmseRow,
    bearing_rmse_table,
    fuse_bearings,
)
from usvfast.bearing.io import (
    AisData,
    SkippedRowsWarning,
    read_ais,
    read_bearing_samples,
    read_cameras,
    write_fusion_csv,
    write_rmse_csv,
)
from usvfast.bearing.sample import BUNDLED_DIR
from usvfast.bearing.tracks import fuse_tracks, looks_like_mot, track_bearings


@dataclass(frozen=True)
class BearingRun:
    """Everything one `run_bearing` produced: the fusion, the AIS reference bearing at the
    sample times (NaN where not covered), the RMSE table and the files written."""

    fusion: BearingFusion
    reference_deg: np.ndarray
    rmse: list[RmseRow]
    files: list[Path]


def plot_fusion(
    path: Path | str, fusion: BearingFusion, reference_deg: np.ndarray, ais: AisData
) -> Path:
    """PNG of the run: bearings per source, fused (±2σ) and AIS; errors against AIS; bearing
    rate (±2σ) with the rate between consecutive AIS reports. Returns the path."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t0 = fusion.times[0]
    t = fusion.times - t0
    # Plot continuous (unwrapped) bearings, shifted back into (-180, 180] as a whole.
    shift = fusion.bearing_deg[0] - fusion.bearing_unwrapped_deg[0]
    fused = fusion.bearing_unwrapped_deg + shift
    measured = fused + wrap_180_deg(fusion.measured_bearing_deg - fused)
    ref = fused + wrap_180_deg(reference_deg - fused)
    ais_t = ais.target.times
    ais_in = (ais_t >= fusion.times[0]) & (ais_t <= fusion.times[-1])
    ais_ref = reference_bearing_deg(ais_t[ais_in], ais.own, ais.target)
    ais_ref_u = unwrap_deg(ais_ref)
    if ais_ref_u.size:
        ais_ref_u += (
            np.round((np.interp(ais_t[ais_in], fusion.times, fused) - ais_ref_u) / 360.0) * 360.0
        )

    fig, axes = plt.subplots(3, 1, figsize=(10, 10), sharex=True, height_ratios=[3, 2, 2])
    ax = axes[0]
    colors = {VISIBLE: "tab:blue", THERMAL: "tab:red"}
    for s in np.unique(fusion.source):
        m = fusion.source == s
        name = SOURCE_NAMES.get(int(s), f"source {int(s)}")
        ax.plot(
            t[m],
            measured[m],
            ".",
            ms=3,
            alpha=0.5,
            color=colors.get(int(s)),
            label=f"{name} camera",
        )
    ax.fill_between(
        t,
        fused - 2 * fusion.bearing_std_deg,
        fused + 2 * fusion.bearing_std_deg,
        color="k",
        alpha=0.2,
        lw=0,
    )
    ax.plot(t, fused, "k-", lw=1.2, label="fused KF + RTS (±2σ)")
    ax.plot(t, ref, "-", color="tab:green", lw=1, label="AIS (interpolated)")
    ax.plot(
        ais_t[ais_in] - t0, ais_ref_u, "o", color="tab:green", ms=5, mfc="none", label="AIS reports"
    )
    ax.set_ylabel("bearing rel. heading [deg]\n(+ = starboard)")
    ax.legend(loc="best", fontsize=8)
    ax.grid(alpha=0.3)

    ax = axes[1]
    for s in np.unique(fusion.source):
        m = fusion.source == s
        name = SOURCE_NAMES.get(int(s), f"source {int(s)}")
        ax.plot(
            t[m],
            measured[m] - ref[m],
            ".",
            ms=3,
            alpha=0.4,
            color=colors.get(int(s)),
            label=f"{name} − AIS",
        )
    ax.plot(t, fused - ref, "k-", lw=1.2, label="fused − AIS")
    ax.axhline(0.0, color="tab:green", lw=0.8)
    ax.set_ylabel("error vs AIS [deg]")
    ax.legend(loc="best", fontsize=8)
    ax.grid(alpha=0.3)

    ax = axes[2]
    rate, rate_std = fusion.bearing_rate_deg_s, fusion.bearing_rate_std_deg_s
    ax.fill_between(t, rate - 2 * rate_std, rate + 2 * rate_std, color="k", alpha=0.2, lw=0)
    ax.plot(t, rate, "k-", lw=1.2, label="fused bearing rate (±2σ)")
    if ais_ref_u.size > 1:
        mid = 0.5 * (ais_t[ais_in][1:] + ais_t[ais_in][:-1]) - t0
        ax.plot(
            mid,
            np.diff(ais_ref_u) / np.diff(ais_t[ais_in]),
            "o",
            color="tab:green",
            ms=5,
            mfc="none",
            label="AIS (between reports)",
        )
    ax.set_ylabel("bearing rate [deg/s]")
    start = unix_to_iso(t0, sep=" ")
    ax.set_xlabel(f"time since {start} UTC [s]")
    ax.legend(loc="best", fontsize=8)
    ax.grid(alpha=0.3)
    fig.suptitle("Vessel bearing: visible + thermal cameras fused (KF + RTS) vs AIS")
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def run_bearing(
    samples_csv: Path | str,
    ais_csv: Path | str,
    out_dir: Path | str,
    *,
    cameras_json: Path | str | None = None,
    visible_std_deg: float = PAPER_MEASUREMENT_STD_DEG[VISIBLE],
    thermal_std_deg: float = PAPER_MEASUREMENT_STD_DEG[THERMAL],
    noise_diff_coeff_deg2: float = PAPER_NOISE_DIFF_COEFF_DEG2,
    plot: bool = True,
) -> BearingRun:
    """Read the samples and AIS CSVs (formats: `usvfast.bearing.io`; sources 1 visible and
    2 thermal), fuse, evaluate against AIS and write `fused_bearing.csv`, `rmse.csv` and
    (if `plot`) `bearing.png` into out_dir.

    Bad rows are skipped with a `SkippedRowsWarning`; raises ValueError when a file is
    unusable.
    """
    cameras = None if cameras_json is None else read_cameras(cameras_json)
    samples = read_bearing_samples(samples_csv, cameras)
    ais = read_ais(ais_csv)
    fusion = fuse_bearings(
        samples.source,
        samples.times,
        samples.bearing_deg,
        samples.confidence,
        measurement_std_deg={VISIBLE: visible_std_deg, THERMAL: thermal_std_deg},
        noise_diff_coeff_deg2=noise_diff_coeff_deg2,
    )
    reference = reference_bearing_deg(fusion.times, ais.own, ais.target)
    rmse = bearing_rmse_table(fusion, reference)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    files = [
        write_fusion_csv(out / "fused_bearing.csv", fusion, reference),
        write_rmse_csv(out / "rmse.csv", rmse),
    ]
    if plot:
        files.append(plot_fusion(out / "bearing.png", fusion, reference, ais))
    return BearingRun(fusion, reference, rmse, files)


@dataclass(frozen=True)
class TrackBearingRun:
    """What `run_track_bearing` produced: the fusion per track id, the AIS reference at each
    track's sample times, each track's RMSE table and the files written."""

    fusions: dict[int, BearingFusion]
    reference_deg: dict[int, np.ndarray]
    rmse: dict[int, list[RmseRow]]
    files: list[Path]


def run_track_bearing(
    tracks_txt: Path | str,
    ais_csv: Path | str,
    out_dir: Path | str,
    *,
    cameras_json: Path | str | None = None,
    source: int = VISIBLE,
    fps: float = 25.0,
    start_time: float = 0.0,
    visible_std_deg: float = PAPER_MEASUREMENT_STD_DEG[VISIBLE],
    thermal_std_deg: float = PAPER_MEASUREMENT_STD_DEG[THERMAL],
    noise_diff_coeff_deg2: float = PAPER_NOISE_DIFF_COEFF_DEG2,
) -> TrackBearingRun:
    """Bearings of an image tracker's tracks.txt (MOTChallenge, `usvfast shore`), one series
    per track id through eq. (1) with camera `source` of cameras_json (default the paper's),
    each fused by KF + RTS and compared with AIS; writes `fused_track_ID.csv` per track (the
    fused_bearing.csv columns) and `rmse_tracks.csv` (track_id,label,rmse_deg,count)."""
    from usvfast.bearing.io import PAPER_CAMERAS

    cameras = PAPER_CAMERAS if cameras_json is None else read_cameras(cameras_json)
    if source not in cameras:
        raise ValueError(f"source: no camera {source} (have {sorted(cameras)})")
    samples = track_bearings(tracks_txt, cameras[source], fps=fps, start_time=start_time)
    fusions = fuse_tracks(
        samples,
        source=source,
        measurement_std_deg={VISIBLE: visible_std_deg, THERMAL: thermal_std_deg},
        noise_diff_coeff_deg2=noise_diff_coeff_deg2,
    )
    if not fusions:
        raise ValueError(f"tracks: no track with two or more boxes in {tracks_txt}")
    ais = read_ais(ais_csv)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    refs = {t: reference_bearing_deg(f.times, ais.own, ais.target) for t, f in fusions.items()}
    rmse = {t: bearing_rmse_table(f, refs[t]) for t, f in fusions.items()}
    files = [write_fusion_csv(out / f"fused_track_{t}.csv", f, refs[t]) for t, f in fusions.items()]
    rmse_path = out / "rmse_tracks.csv"
    with rmse_path.open("w", encoding="utf-8") as fh:
        fh.write("track_id,label,rmse_deg,count\n")
        for t, rows in rmse.items():
            fh.writelines(f"{t},{r.label},{r.rmse_deg:.4f},{r.count}\n" for r in rows)
    files.append(rmse_path)
    return TrackBearingRun(fusions, refs, rmse, files)


def _rmse_table(rmse: list[RmseRow]) -> Table:
    table = Table(title="Bearing RMSE against AIS (Table 1 of Gorad et al. 2023)")
    table.add_column("estimate")
    table.add_column("RMSE (deg)", justify="right")
    table.add_column("samples", justify="right")
    for row in rmse:
        table.add_row(row.label, f"{row.rmse_deg:.3f}", str(row.count))
    return table


def _run_and_report(
    samples: Path, ais: Path, out: Path, cameras: Path | None, **kwargs: Any
) -> None:
    console, err = Console(), Console(stderr=True)
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", SkippedRowsWarning)
            run = run_bearing(samples, ais, out, cameras_json=cameras, **kwargs)
    except ValueError as exc:
        err.print(f"[red]error:[/red] {escape(str(exc))}", soft_wrap=True)
        raise typer.Exit(code=1) from exc
    for w in caught:
        if issubclass(w.category, SkippedRowsWarning):
            err.print(f"[yellow]warning:[/yellow] {escape(str(w.message))}", soft_wrap=True)
        else:
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    covered = int(np.isfinite(run.reference_deg).sum())
    console.print(
        f"{len(run.fusion.times)} samples over {run.fusion.times[-1] - run.fusion.times[0]:.1f} s, "
        f"{covered} covered by AIS"
    )
    console.print(_rmse_table(run.rmse))
    for path in run.files:
        console.print(f"wrote {escape(str(path))}", soft_wrap=True)


def _tracks_and_report(
    tracks: Path,
    ais: Path,
    out: Path,
    cameras: Path | None,
    *,
    source: int,
    fps: float,
    start_time: float,
    visible_std_deg: float,
    thermal_std_deg: float,
    noise_diff_coeff_deg2: float,
) -> None:
    console, err = Console(), Console(stderr=True)
    try:
        run = run_track_bearing(
            tracks,
            ais,
            out,
            cameras_json=cameras,
            source=source,
            fps=fps,
            start_time=start_time,
            visible_std_deg=visible_std_deg,
            thermal_std_deg=thermal_std_deg,
            noise_diff_coeff_deg2=noise_diff_coeff_deg2,
        )
    except ValueError as exc:
        err.print(f"[red]error:[/red] {escape(str(exc))}", soft_wrap=True)
        raise typer.Exit(code=1) from exc
    table = Table(title="Bearing RMSE against AIS per image track (KF + RTS)")
    for col in ("track", "samples", "RMSE (deg)", "AIS-covered"):
        table.add_column(col, justify="right")
    for t, rows in run.rmse.items():
        fused = rows[-1]
        table.add_row(
            str(t), str(len(run.fusions[t].times)), f"{fused.rmse_deg:.3f}", str(fused.count)
        )
    console.print(table)
    for path in run.files:
        console.print(f"wrote {escape(str(path))}", soft_wrap=True)


def bearing_command(
    samples: Annotated[
        Path,
        typer.Argument(
            help="Samples CSV: source,t,bearing_deg[,confidence] or "
            "source,t,x_px,y_px[,confidence,pan_deg,tilt_deg,zoom]."
        ),
    ],
    ais: Annotated[
        Path, typer.Argument(help="AIS CSV: vessel(own|target),t,lat_deg,lon_deg,heading_deg.")
    ],
    out: Annotated[Path, typer.Option(help="Output directory.")] = Path("out/bearing"),
    cameras: Annotated[
        Path | None,
        typer.Option(help="Cameras JSON for pixel samples (default: the paper's calibration)."),
    ] = None,
    visible_std_deg: Annotated[
        float, typer.Option(help="Bearing noise std of source 1 (visible), degrees.")
    ] = PAPER_MEASUREMENT_STD_DEG[VISIBLE],
    thermal_std_deg: Annotated[
        float, typer.Option(help="Bearing noise std of source 2 (thermal), degrees.")
    ] = PAPER_MEASUREMENT_STD_DEG[THERMAL],
    noise_diff_coeff_deg2: Annotated[
        float, typer.Option(help="Wiener velocity process noise q, deg²/s³.")
    ] = PAPER_NOISE_DIFF_COEFF_DEG2,
    tracks_fps: Annotated[
        float, typer.Option(help="Frame rate of a tracks.txt SAMPLES file (frames/s).")
    ] = 25.0,
    tracks_start: Annotated[
        float, typer.Option(help="UNIX time of frame 1 of a tracks.txt SAMPLES file (s).")
    ] = 0.0,
    tracks_source: Annotated[
        int, typer.Option(help="Camera (source id in --cameras) of a tracks.txt file.")
    ] = VISIBLE,
) -> None:
    """Fuse visible + thermal camera bearings (KF + RTS) and compare them with AIS.

    Writes fused_bearing.csv, rmse.csv and bearing.png into --out and prints the RMSE table.
    SAMPLES may also be an image tracker's tracks.txt (MOTChallenge, `usvfast shore`): then
    each track id gives one bearing series (box centres through eq. 1 with camera
    --tracks-source), fused on its own; writes fused_track_ID.csv per track and rmse_tracks.csv.
    """
    if looks_like_mot(samples):
        _tracks_and_report(
            samples,
            ais,
            out,
            cameras,
            source=tracks_source,
            fps=tracks_fps,
            start_time=tracks_start,
            visible_std_deg=visible_std_deg,
            thermal_std_deg=thermal_std_deg,
            noise_diff_coeff_deg2=noise_diff_coeff_deg2,
        )
        return
    _run_and_report(
        samples,
        ais,
        out,
        cameras,
        visible_std_deg=visible_std_deg,
        thermal_std_deg=thermal_std_deg,
        noise_diff_coeff_deg2=noise_diff_coeff_deg2,
    )


def demo_command(
    out: Annotated[Path, typer.Option(help="Output directory.")] = Path("out/demo"),
) -> None:
    """Main job on the bundled sample: bearing fusion of visible + thermal cameras vs AIS."""
    Console().print(f"bundled sample: {escape(str(BUNDLED_DIR))}", soft_wrap=True)
    _run_and_report(
        BUNDLED_DIR / "samples.csv", BUNDLED_DIR / "ais.csv", out, BUNDLED_DIR / "cameras.json"
    )
