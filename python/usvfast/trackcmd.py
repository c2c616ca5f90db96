"""`usvfast track PLOTS --config CFG --out DIR`: track position plots from a file.

PLOTS is the Joyride `.mat` recording (`usvfast.datasets.load_joyride`) or a CSV with header
`time,north,east[,sensor][,own_north,own_east]` (seconds, metres in a local north/east plane;
rows of equal time are one scan; damaged rows are skipped and counted; `own_*` the radar's
position, needed by `polar_noise` and `bearing_correction_deg`). CFG is a TOML file or the
name of a shipped preset (`python/usvfast/presets/NAME.toml`, e.g. `joyride`); its
`[tracker]` table is read by `tracker_from_config`. Writes DIR/tracks.csv (`time,track_id,
north,east,v_north,v_east,cov_nn,cov_ne,cov_ee`, one row per confirmed track per scan, and
`turn_rate,var_turn_rate` (rad/s, rad²/s²) after them when the IMM estimates the turn rate) and
DIR/summary.json (counts, time per scan, and with Joyride's GNSS truth the figures of
`usvfast.metrics.track_quality`).
"""

from __future__ import annotations

import csv
import json
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Any

import numpy as np
import tomllib
import typer

from usvfast import tracking as tk
from usvfast.kalman import constant_velocity_2d

PRESETS = Path(__file__).parent / "presets"

_TOP = {
    "q",
    "sigma",
    "association",
    "prob_detect",
    "prob_gate",
    "clutter_density",
    "missed_distance",
    "delete_steps",
    "initiate_in_gates",
    "polar_noise",
    "bearing_correction_deg",
    "initiator",
    "imm",
    "existence",
}
_INIT = {
    "min_points",
    "delete_steps",
    "missed_distance",
    "prior_velocity_var",
    "prior_turn_rate_var",
    "imm",
}
_IMM = {
    "turn_rates",
    "turn_q",
    "stay",
    "cv_q",
    "ct_q",
    "ct_q_turn",
    "ct_predictor",
    "cv_q_turn",
}
_EXIST = {"survival", "initial", "delete", "vis_stay", "invis_stay", "confirm", "birth", "joint"}


def load_config(config: str | Path) -> dict[str, Any]:
    """The `[tracker]` table of a TOML file, or of the shipped preset named `config`."""
    p = Path(config)
    if not p.is_file():
        p = PRESETS / f"{config}.toml"
        if not p.is_file():
            names = sorted(f.stem for f in PRESETS.glob("*.toml"))
            raise ValueError(f"config: no file {config!r} and no preset of that name ({names})")
    with p.open("rb") as fh:
        data = tomllib.load(fh)
    if "tracker" not in data:
        raise ValueError(f"config: {p} has no [tracker] table")
    return data["tracker"]


def _check_keys(table: dict[str, Any], allowed: set[str], where: str) -> None:
    bad = sorted(set(table) - allowed)
    if bad:
        raise ValueError(f"{where}: unknown key(s) {bad} (allowed: {sorted(allowed)})")


def tracker_from_config(cfg: dict[str, Any]) -> tk.Tracker:
    """A position-plot `Tracker` (state [n, v_n, e, v_e], one sensor with R = sigma² I) from a
    `[tracker]` table; unknown keys raise ValueError naming them. With `polar_noise` the plots'
    own covariances (`plot_covariances`) replace R: pass them to `run`/`step`."""
    _check_keys(cfg, _TOP, "tracker")
    init = dict(cfg.get("initiator", {}))
    _check_keys(init, _INIT, "tracker.initiator")
    q = float(cfg.get("q", 5.0))
    if cfg.get("association", "jpda") == "jpda":
        assoc: Any = tk.JPDA(
            float(cfg.get("prob_detect", 0.9)),
            float(cfg.get("prob_gate", 0.999)),
            float(cfg.get("clutter_density", 1e-6)),
        )
    elif cfg["association"] == "gnn":
        assoc = tk.GNN(missed_distance=float(cfg.get("missed_distance", 4.0)))
    else:
        raise ValueError(f"tracker.association: 'jpda' or 'gnn', got {cfg['association']!r}")
    imm, ndim, q_w = _imm_from_config(cfg, q)
    existence = None
    if "existence" in cfg:
        e = dict(cfg["existence"])
        _check_keys(e, _EXIST, "tracker.existence")
        joint = e.pop("joint", False)
        if not isinstance(joint, bool):
            raise ValueError(f"tracker.existence.joint: true or false, got {joint!r}")
        existence = tk.Existence(**{k: float(v) for k, v in e.items()}, joint=joint)
    init_imm = init.get("imm", False)
    if not isinstance(init_imm, bool):
        raise ValueError(f"tracker.initiator.imm: true or false, got {init_imm!r}")
    if init_imm and imm is None:
        raise ValueError("tracker.initiator.imm: needs a [tracker.imm] table (the bank it runs)")
    pvv = float(init.get("prior_velocity_var", 100.0))
    prior = [0.0, pvv, 0.0, pvv]
    motion: Any = constant_velocity_2d(q)
    if ndim == 5:
        prior.append(float(init.get("prior_turn_rate_var", 0.01)))
        motion = tk.constant_velocity_turn_rate(q, q_w)
    elif "prior_turn_rate_var" in init:
        raise ValueError("tracker.initiator.prior_turn_rate_var: needs [tracker.imm] ct_q")
    return tk.Tracker(
        motion_model=motion,
        sensors=[tk.Sensor.position(float(cfg.get("sigma", 20.0)), ndim_state=ndim)],
        association=assoc,
        deleter=tk.StepsSinceUpdate(int(cfg.get("delete_steps", 50))),
        initiator=tk.MultiMeasurementInitiator(
            np.zeros(ndim),
            np.diag(prior),
            min_points=int(init.get("min_points", 2)),
            deleter=tk.StepsSinceUpdate(int(init.get("delete_steps", 3))),
            missed_distance=float(init.get("missed_distance", 5.0)),
            imm=init_imm,
        ),
        initiate_in_gates=bool(cfg.get("initiate_in_gates", False)),
        imm=imm,
        existence=existence,
    )


def _imm_from_config(cfg: dict[str, Any], q: float) -> tuple[tk.IMM | None, int, float]:
    """The `[tracker.imm]` table as an `IMM`, the state dimension (4, or 5 with `ct_q`: the
    turn rate in the state) and the turn-rate noise of the constant-velocity modes (rad² s⁻³).

    Modes: CV(q), more CV modes (`cv_q`), then either known-rate turns (`turn_rates`, `turn_q`;
    4-D state) or `ConstantTurn` modes (`ct_q` velocity noises with `ct_q_turn` turn-rate
    noises, one per mode, `ct_predictor` "ekf"/"ukf"; 5-D state whose CV modes carry ω as a
    random walk of noise `cv_q_turn`). `stay`: P(same mode next scan), the rest spread evenly."""
    if "imm" not in cfg:
        return None, 4, 0.0
    t = dict(cfg["imm"])
    _check_keys(t, _IMM, "tracker.imm")
    ct = "ct_q" in t
    if ct and "turn_rates" in t:
        raise ValueError(
            "tracker.imm: turn_rates (known-rate turns on [n, v_n, e, v_e]) and ct_q (the turn "
            "rate in the state) cannot share one bank"
        )
    if not ct and "turn_rates" not in t:
        raise ValueError("tracker.imm: needs turn_rates or ct_q")
    for k in ("ct_q_turn", "ct_predictor", "cv_q_turn"):
        if k in t and not ct:
            raise ValueError(f"tracker.imm.{k}: needs ct_q")
    if "turn_q" in t and ct:
        raise ValueError("tracker.imm.turn_q: the known-rate turns' noise, needs turn_rates")
    q_w = float(t.get("cv_q_turn", 0.0))
    if ct:
        cqs = [float(v) for v in _as_list(t["ct_q"], "ct_q")]
        qts = [float(v) for v in _as_list(t.get("ct_q_turn", [1e-3]), "ct_q_turn")]
        if len(qts) == 1:
            qts *= len(cqs)
        if len(qts) != len(cqs):
            raise ValueError(
                f"tracker.imm.ct_q_turn: one value or one per ct_q ({len(cqs)}), got {len(qts)}"
            )
        cv = [tk.constant_velocity_turn_rate(q, q_w)]
        cv += [tk.constant_velocity_turn_rate(float(v), q_w) for v in t.get("cv_q", [])]
        pred = t.get("ct_predictor", "ukf")
        modes: list[Any] = cv + [tk.ConstantTurn(a, b, pred) for a, b in zip(cqs, qts, strict=True)]
    else:
        modes = [constant_velocity_2d(q)]
        modes += [constant_velocity_2d(float(v)) for v in t.get("cv_q", [])]
        modes += [tk.KnownTurnRate(float(t.get("turn_q", q)), float(w)) for w in t["turn_rates"]]
    r, stay = len(modes), float(t.get("stay", 0.95))
    m = np.full((r, r), (1.0 - stay) / max(r - 1, 1))
    np.fill_diagonal(m, stay)
    return tk.IMM(modes, m), 5 if ct else 4, q_w


def _as_list(v: Any, name: str) -> list[Any]:
    """A TOML number or array as a list."""
    if isinstance(v, list):
        return v
    if isinstance(v, int | float) and not isinstance(v, bool):
        return [v]
    raise ValueError(f"tracker.imm.{name}: a number or an array of numbers, got {v!r}")


@dataclass(frozen=True)
class Plots:
    """Scans of plots: times (s,), plots (d, 2) north/east m, scan_index (d,), sensor (d,);
    truth (s, 2) north/east when the file has it; skipped damaged rows; origins (d, 2) the
    radar's north/east at each plot when known."""

    times: np.ndarray
    plots: np.ndarray
    scan_index: np.ndarray
    sensor: np.ndarray
    truth: np.ndarray | None = None
    skipped: int = 0
    origins: np.ndarray | None = None


def polar_covariances(
    plots: np.ndarray, origins: np.ndarray, range_std: float, bearing_std_deg: float
) -> np.ndarray:
    """(d, 2, 2) north/east covariance (m²) of each radar plot (d, 2) seen from its radar
    position origins (d, 2), for independent range and bearing errors of standard deviations
    range_std (m) and bearing_std_deg (degrees): J diag(σ_ρ², σ_φ²) Jᵀ with J the Jacobian of
    (φ, ρ) -> (n, e) = origin + ρ (cos φ, sin φ) at the plot (the converted-measurement
    covariance, Bar-Shalom, Li & Kirubarajan 2001, §10.4.3). Plots closer than 1 m to their
    origin use ρ = 1 m."""
    rel = np.asarray(plots, float) - np.asarray(origins, float)
    rng = np.maximum(np.hypot(rel[:, 0], rel[:, 1]), 1.0)
    c, s = rel[:, 0] / rng, rel[:, 1] / rng
    rr, tt = range_std**2, (rng * np.radians(bearing_std_deg)) ** 2
    cov = np.empty((len(rel), 2, 2))
    cov[:, 0, 0] = c * c * rr + s * s * tt
    cov[:, 1, 1] = s * s * rr + c * c * tt
    cov[:, 0, 1] = cov[:, 1, 0] = c * s * (rr - tt)
    return cov


def plot_covariances(cfg: dict[str, Any], plots: Plots) -> np.ndarray | None:
    """Per-plot covariances of `cfg`'s `polar_noise = [range_std m, bearing_std deg]` (None
    without it: every plot then has R = sigma² I)."""
    if "polar_noise" not in cfg:
        return None
    pn = cfg["polar_noise"]
    ok = isinstance(pn, list) and len(pn) == 2
    ok = ok and all(isinstance(v, int | float) and not isinstance(v, bool) for v in pn)
    if not (ok and all(np.isfinite(v) and v > 0 for v in pn)):
        raise ValueError(
            f"tracker.polar_noise: [range_std m, bearing_std deg], both > 0, got {pn!r}"
        )
    if plots.origins is None:
        raise ValueError("tracker.polar_noise: the plots need radar positions (own_north/east)")
    z = corrected_plots(cfg, plots)
    return polar_covariances(z, plots.origins, float(pn[0]), float(pn[1]))


def corrected_plots(cfg: dict[str, Any], plots: Plots) -> np.ndarray:
    """(d, 2) plots turned about their radar positions by `cfg`'s `bearing_correction_deg`
    (degrees added to every plot's compass bearing; default 0: the plots as given). This is
    a calibration of the radar's heading alignment, measured against a reference (AIS or GNSS
    of a known target) outside the tracker: the tracker cannot estimate it, since a turned
    picture of a boat's track is as likely under its motion models as the true one."""
    raw = cfg.get("bearing_correction_deg", 0.0)
    deg = float(raw) if isinstance(raw, int | float) and not isinstance(raw, bool) else np.nan
    if not np.isfinite(deg) or abs(deg) > 180.0:
        raise ValueError(f"tracker.bearing_correction_deg: degrees in [-180, 180], got {raw!r}")
    if deg == 0.0:
        return plots.plots
    if plots.origins is None:
        raise ValueError(
            "tracker.bearing_correction_deg: the plots need radar positions (own_north/east)"
        )
    c, s = np.cos(np.radians(deg)), np.sin(np.radians(deg))
    rel = plots.plots - plots.origins
    # Compass bearings (clockwise from north) grow by deg: (n, e) -> R(deg) (n, e).
    return plots.origins + np.stack(
        [c * rel[:, 0] - s * rel[:, 1], s * rel[:, 0] + c * rel[:, 1]], axis=1
    )


def read_plots(path: Path) -> Plots:
    """Joyride `.mat` or CSV `time,north,east[,sensor]` (see the module docstring)."""
    if path.suffix.lower() == ".mat":
        from usvfast.datasets import load_joyride

        rec = load_joyride(path)
        si, plots = rec.scan_arrays()
        return Plots(
            rec.times,
            plots,
            si,
            np.zeros(len(plots), np.int64),
            rec.target[:, [0, 2]],
            rec.skipped_scans + rec.skipped_plots,
            rec.ownship[si][:, [0, 2]],
        )
    rows, skipped = [], 0
    with path.open(newline="") as fh:
        reader = csv.DictReader(fh)
        need = {"time", "north", "east"}
        cols = set(reader.fieldnames or ())
        if not need <= cols:
            raise ValueError(f"plots: {path} needs columns time,north,east[,sensor]")
        own = {"own_north", "own_east"} <= cols
        for r in reader:
            try:
                v = (
                    float(r["time"]),
                    float(r["north"]),
                    float(r["east"]),
                    int(r.get("sensor") or 0),
                    float(r["own_north"]) if own else 0.0,
                    float(r["own_east"]) if own else 0.0,
                )
            except (TypeError, ValueError):
                skipped += 1
                continue
            if not all(np.isfinite(v[:3] + v[4:])) or v[3] != 0:
                skipped += 1  # one position sensor (R = sigma² I) is configured
                continue
            rows.append(v)
    if not rows:
        raise ValueError(f"plots: no usable row in {path} ({skipped} skipped)")
    a = np.array(rows, dtype=float)
    a = a[np.argsort(a[:, 0], kind="stable")]
    times, si = np.unique(a[:, 0], return_inverse=True)
    return Plots(
        times,
        a[:, 1:3].copy(),
        si.astype(np.int64),
        np.zeros(len(a), np.int64),
        None,
        skipped,
        a[:, 4:6].copy() if own else None,
    )


def run_tracking(plots: Plots, cfg: dict[str, Any]) -> tuple[tk.RunResult, float]:
    """The tracker of `cfg` over `plots` (times relative to the first scan); returns the run and
    its time per scan (ms)."""
    tracker = tracker_from_config(cfg)
    t0 = time.perf_counter()
    cov = plot_covariances(cfg, plots)
    res = tracker.run(
        plots.times - plots.times[0],
        corrected_plots(cfg, plots),
        plots.sensor,
        plots.scan_index,
        covariances=cov,
    )
    ms = (time.perf_counter() - t0) / max(len(plots.times), 1) * 1e3
    return res, ms


def track_command(
    plots: Annotated[Path, typer.Argument(help="Joyride .mat or CSV time,north,east[,sensor]")],
    config: Annotated[str, typer.Option(help="TOML file or preset name")] = "joyride",
    out: Annotated[Path, typer.Option(help="Output directory")] = Path("track-out"),
) -> None:
    """Track position plots and write DIR/tracks.csv and DIR/summary.json."""
    try:
        cfg = load_config(config)
        data = read_plots(plots)
        res, ms = run_tracking(data, cfg)
    except (ValueError, FileNotFoundError) as exc:
        typer.echo(f"error: {exc}", err=True)
        raise typer.Exit(2) from exc
    out.mkdir(parents=True, exist_ok=True)
    # The state's first four entries are [n, v_n, e, v_e]; a fifth is the turn rate (rad/s).
    turn = res.state.shape[1] >= 5
    with (out / "tracks.csv").open("w", newline="") as fh:
        w = csv.writer(fh)
        head = ["time", "track_id", "north", "east", "v_north", "v_east"]
        w.writerow(
            head + ["cov_nn", "cov_ne", "cov_ee"] + (["turn_rate", "var_turn_rate"] if turn else [])
        )
        for s, i, x, p in zip(res.scan, res.track_id, res.state, res.covariance, strict=True):
            cells = [x[0], x[2], x[1], x[3], p[0, 0], p[0, 2], p[2, 2]]
            cells += [x[4], p[4, 4]] if turn else []
            w.writerow([repr(float(data.times[s])), int(i), *(repr(float(v)) for v in cells)])
    summary: dict[str, Any] = {
        "scans": len(data.times),
        "plots": len(data.plots),
        "skipped_records": data.skipped,
        "track_rows": len(res.scan),
        "tracks": len(np.unique(res.track_id)),
        "ms_per_scan": ms,
    }
    if data.truth is not None:
        from usvfast.metrics import track_quality

        q = track_quality(data.truth, res.scan, res.track_id, res.state[:, [0, 2]])
        summary |= {
            "rmse_m": q.rmse,
            "coverage": q.coverage,
            "fragments": q.fragments,
            "false_tracks": q.tracks_elsewhere,
        }
    (out / "summary.json").write_text(json.dumps(summary, indent=2))
    typer.echo(json.dumps(summary))
