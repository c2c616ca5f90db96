"""The "plots" job: radar plots tracked by a configured tracker, scored against the truth."""

from __future__ import annotations

import copy
import time
from pathlib import Path
from typing import Any

import numpy as np

from usvfast.sweep.spec import Job

# The Joyride tracker chosen on the real recording (README "Joyride"): CV JPDA.
JOYRIDE = {
    "tracker": {
        "q": 5.0,
        "sigma": 25.0,
        "prob_detect": 0.8,
        "clutter_density": 5e-7,
        "prob_gate": 0.999,
        "delete_steps": 50,
        "init_steps": 3,
        "missed_distance": 5.0,
        "min_points": 2,
        "prior_velocity_var": 100.0,
        "initiate_in_gates": False,
    },
    "metrics": {"gate": 50.0},
}
PRESETS = {"joyride": JOYRIDE}


def with_overrides(config: dict[str, Any], overrides: dict[str, Any]) -> dict[str, Any]:
    """A copy of `config` with dotted keys ("tracker.q") set; an unknown key is a ValueError
    naming it (a typo must not silently run the base configuration)."""
    out = copy.deepcopy(config)
    for key, value in overrides.items():
        *tables, leaf = key.split(".")
        node = out
        for t in tables:
            if not isinstance(node.get(t), dict):
                raise ValueError(f"params: {key!r} is not a key of the base configuration")
            node = node[t]
        if leaf not in node:
            raise ValueError(f"params: {key!r} is not a key of the base configuration")
        node[leaf] = value
    return out


def _tracker(c: dict[str, Any]):
    from usvfast import tracking as tk
    from usvfast.kalman import constant_velocity_2d

    v = c["prior_velocity_var"]
    return tk.Tracker(
        motion_model=constant_velocity_2d(c["q"]),
        sensors=[tk.Sensor.position(noise_std=c["sigma"])],
        association=tk.JPDA(
            prob_detect=c["prob_detect"],
            prob_gate=c["prob_gate"],
            clutter_density=c["clutter_density"],
        ),
        deleter=tk.StepsSinceUpdate(int(c["delete_steps"])),
        initiator=tk.MultiMeasurementInitiator(
            prior_state=np.zeros(4),
            prior_covariance=np.diag([0, v, 0, v]),
            min_points=int(c["min_points"]),
            deleter=tk.StepsSinceUpdate(int(c["init_steps"])),
            missed_distance=c["missed_distance"],
        ),
        initiate_in_gates=bool(c["initiate_in_gates"]),
    )


def plots_job(job: Job) -> tuple[dict[str, Any], dict[str, float]]:
    """Track the job's plot file; metrics of `usvfast.metrics.track_quality` and `clear_mot`
    against the recording's own truth (Joyride's GNSS)."""
    from usvfast.datasets import load_joyride
    from usvfast.metrics import clear_mot, track_quality

    if job.base not in PRESETS:
        raise ValueError(f"base: unknown preset {job.base!r} (known: {sorted(PRESETS)})")
    config = with_overrides(PRESETS[job.base], job.params)
    t0 = time.perf_counter()
    rec = load_joyride(job.recording)
    t1 = time.perf_counter()
    tracker = _tracker(config["tracker"])
    scan_index, plots = rec.scan_arrays()
    res = tracker.run(rec.times - rec.times[0], plots, np.zeros(len(plots), np.int64), scan_index)
    t2 = time.perf_counter()
    truth = rec.target[:, [0, 2]]
    gate = float(config["metrics"]["gate"])
    pos = res.state[:, [0, 2]]
    q = track_quality(truth, res.scan, res.track_id, pos, gate=gate)
    mot = clear_mot(truth, res.scan, res.track_id, pos, gate=gate)
    if job.tracks_dir is not None:
        out = Path(job.tracks_dir)
        out.mkdir(parents=True, exist_ok=True)
        rows = np.column_stack([rec.times[res.scan], res.track_id, res.state])
        header = "time,track_id,north,v_north,east,v_east"
        np.savetxt(out / "tracks.csv", rows, delimiter=",", header=header, comments="")
    metrics = {
        "rmse": q.rmse,
        "coverage": q.coverage,
        "fragments": q.fragments,
        "tracks_elsewhere": q.tracks_elsewhere,
        "n_tracks": q.n_tracks,
        "mota": mot.mota,
        "motp": mot.motp,
        "ms_per_scan": 1e3 * (t2 - t1) / rec.n_scans,
    }
    return metrics, {"read": t1 - t0, "track": t2 - t1, "metrics": time.perf_counter() - t2}
