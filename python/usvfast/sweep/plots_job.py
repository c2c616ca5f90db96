"""The "plots" job: radar plots tracked by `usvfast track`'s tracker, scored against the truth."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import numpy as np

from usvfast.sweep.spec import Job


def plots_job(job: Job) -> tuple[dict[str, Any], dict[str, float]]:
    """Track the job's plot file (Joyride `.mat` or CSV `time,north,east`) with the `[tracker]`
    table of `base` (a preset name such as "joyride", or a TOML file) and the job's dotted
    overrides ("tracker.q", "tracker.imm.turn_q"; the parameter "base" picks another preset);
    metrics of `usvfast.metrics.track_quality` / `clear_mot` against the file's truth (Joyride's
    GNSS), gate 50 m unless the parameter "gate" says otherwise."""
    from usvfast.metrics import clear_mot, track_quality
    from usvfast.pipeline.config import apply_overrides
    from usvfast.trackcmd import load_config, read_plots, run_tracking

    params = dict(job.params)
    base = str(params.pop("base", job.base))
    gate = float(params.pop("gate", 50.0))
    config = apply_overrides({"tracker": load_config(base)}, params)["tracker"]
    t0 = time.perf_counter()
    plots = read_plots(Path(job.recording))
    t1 = time.perf_counter()
    res, ms_per_scan = run_tracking(plots, config)
    t2 = time.perf_counter()
    if job.tracks_dir is not None:
        out = Path(job.tracks_dir)
        out.mkdir(parents=True, exist_ok=True)
        rows = np.column_stack([plots.times[res.scan], res.track_id, res.state])
        # The state's first four entries are [n, v_n, e, v_e]; a fifth is the turn rate.
        header = "time,track_id,north,v_north,east,v_east" + (
            ",turn_rate" if res.state.shape[1] >= 5 else ""
        )
        np.savetxt(out / "tracks.csv", rows, delimiter=",", header=header, comments="")
    metrics: dict[str, Any] = {"ms_per_scan": ms_per_scan, "scans": len(plots.times)}
    if plots.truth is not None:
        pos = res.state[:, [0, 2]]
        q = track_quality(plots.truth, res.scan, res.track_id, pos, gate=gate)
        mot = clear_mot(plots.truth, res.scan, res.track_id, pos, gate=gate)
        metrics.update(
            rmse=q.rmse,
            coverage=q.coverage,
            fragments=q.fragments,
            tracks_elsewhere=q.tracks_elsewhere,
            n_tracks=q.n_tracks,
            mota=mot.mota,
            motp=mot.motp,
        )
    return metrics, {"read": t1 - t0, "track": t2 - t1, "metrics": time.perf_counter() - t2}
