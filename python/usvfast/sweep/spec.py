"""Sweep specifications: recordings × parameter sets, read from TOML, expanded into jobs.

A spec names the recordings (paths or globs, relative to the spec file), each with its ground
truth, the base configuration every job starts from, and the parameters to vary: a full grid
(`[grid]`, every combination) or a random / Latin-hypercube search with a budget (`[search]`).
Parameter names are dotted keys into the base configuration (`"tracker.q"`).

Example (`configs/sweep-joyride.toml`)::

    [sweep]
    name = "joyride q x sigma"
    kind = "plots"                 # radar plot files tracked by `usvfast track`
    base = "joyride"               # a preset name or a config file
    recordings = ["../tests/data/joyride/joyride.mat"]

    [grid]
    "tracker.q" = [1.0, 2.0, 5.0, 10.0, 20.0, 50.0]
    "tracker.sigma" = [10.0, 15.0, 20.0, 25.0, 30.0, 40.0]
"""

from __future__ import annotations

import glob
import hashlib
import itertools
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import tomllib

Value = float | int | str | bool
JOB_KINDS = ("plots", "pipeline")


@dataclass(frozen=True)
class Job:
    """One run of one recording with one parameter set.

    job_id: stable 16-hex-digit hash of everything that defines the run (so a resumed sweep
    recognises finished jobs); kind: "plots", "pipeline" or "module:function" (a user job);
    recording / truth: absolute paths (truth None when the recording carries its own or none);
    base: preset name or absolute config path; params: dotted key -> value overrides;
    tracks_dir: folder the worker writes the job's tracks to, None for metrics only.
    """

    job_id: str
    kind: str
    recording: str
    truth: str | None
    base: str
    params: dict[str, Value]
    tracks_dir: str | None = None


@dataclass(frozen=True)
class SweepSpec:
    """A parsed spec: jobs in a fixed order (recording-major), plus what the summary ranks by
    (`metric`, lower is better unless `maximize`)."""

    name: str
    path: Path
    jobs: list[Job]
    parameters: list[str]
    metric: str = "rmse"
    maximize: bool = False
    extra: dict[str, Any] = field(default_factory=dict)


def _job_id(kind: str, recording: str, truth: str | None, base: str, params: dict) -> str:
    key = json.dumps([kind, recording, truth, base, sorted(params.items())], default=str)
    return hashlib.sha1(key.encode()).hexdigest()[:16]


def _err(path: Path, msg: str) -> ValueError:
    return ValueError(f"{path}: {msg}")


def _recordings(spec: dict, path: Path) -> list[tuple[str, str | None]]:
    """[(recording, truth)] from `recordings` = a list of paths/globs or of tables
    {path, truth}; globs expand in sorted order; every file must exist."""
    raw = spec.get("recordings")
    if not isinstance(raw, list) or not raw:
        raise _err(path, "sweep.recordings: expected a non-empty list of paths or tables")
    out: list[tuple[str, str | None]] = []
    for i, item in enumerate(raw):
        if isinstance(item, str):
            pattern, truth = item, None
        elif isinstance(item, dict) and isinstance(item.get("path"), str):
            unknown = set(item) - {"path", "truth"}
            if unknown:
                raise _err(path, f"sweep.recordings[{i}]: unknown key(s) {sorted(unknown)}")
            pattern, truth = item["path"], item.get("truth")
        else:
            raise _err(path, f"sweep.recordings[{i}]: expected a path or {{path, truth}}")
        base = path.parent
        matches = sorted(glob.glob(str(base / pattern))) if glob.has_magic(pattern) else []
        files = matches or [str(base / pattern)]
        for f in files:
            if not Path(f).exists():
                raise _err(path, f"sweep.recordings[{i}]: {f} does not exist")
            t = None
            if truth is not None:
                t = str((base / truth.format(stem=Path(f).stem, dir=Path(f).parent)).resolve())
                if not Path(t).exists():
                    raise _err(path, f"sweep.recordings[{i}].truth: {t} does not exist")
            out.append((str(Path(f).resolve()), t))
    return out


def _scalar(path: Path, where: str, v: Any) -> Value:
    if isinstance(v, bool | int | float | str):
        return v
    raise _err(path, f"{where}: expected a number, string or boolean, got {v!r}")


def _grid(path: Path, grid: dict) -> list[dict[str, Value]]:
    names, values = [], []
    for name, vals in grid.items():
        if not isinstance(vals, list) or not vals:
            raise _err(path, f"grid.{name}: expected a non-empty list of values")
        names.append(name)
        values.append([_scalar(path, f"grid.{name}", v) for v in vals])
    return [dict(zip(names, combo, strict=True)) for combo in itertools.product(*values)]


def _search(path: Path, search: dict) -> list[dict[str, Value]]:
    """`budget` points from `ranges` (name = [low, high] or {low, high, log}) by
    `method` = "random" or "lhs" (scipy's Latin hypercube), reproducible from `seed`.
    Integer bounds give integer values."""
    from scipy.stats import qmc

    unknown = set(search) - {"method", "budget", "seed", "ranges"}
    if unknown:
        raise _err(path, f"search: unknown key(s) {sorted(unknown)}")
    method = search.get("method", "lhs")
    if method not in ("random", "lhs"):
        raise _err(path, f"search.method: expected 'random' or 'lhs', got {method!r}")
    budget = search.get("budget")
    if not isinstance(budget, int) or isinstance(budget, bool) or budget < 1:
        raise _err(path, f"search.budget: expected a positive integer, got {budget!r}")
    seed = search.get("seed", 0)
    ranges = search.get("ranges")
    if not isinstance(ranges, dict) or not ranges:
        raise _err(path, "search.ranges: expected a table of name = [low, high]")
    bounds = []
    for name, r in ranges.items():
        if isinstance(r, list) and len(r) == 2:
            lo, hi, log = r[0], r[1], False
        elif isinstance(r, dict) and {"low", "high"} <= set(r):
            lo, hi, log = r["low"], r["high"], bool(r.get("log", False))
        else:
            raise _err(path, f"search.ranges.{name}: expected [low, high] or {{low, high, log}}")
        if not all(isinstance(x, int | float) and not isinstance(x, bool) for x in (lo, hi)):
            raise _err(path, f"search.ranges.{name}: bounds must be numbers")
        if not lo < hi or (log and lo <= 0):
            raise _err(path, f"search.ranges.{name}: need 0 < low < high (log) or low < high")
        bounds.append((name, lo, hi, log))
    d = len(bounds)
    if method == "lhs":
        u = qmc.LatinHypercube(d=d, seed=seed).random(budget)  # pyright: ignore[reportCallIssue]
    else:
        u = np.random.default_rng(seed).random((budget, d))
    points = []
    for row in u:
        p: dict[str, Value] = {}
        for x, (name, lo, hi, log) in zip(row, bounds, strict=True):
            v = float(np.exp(np.log(lo) + x * np.log(hi / lo)) if log else lo + x * (hi - lo))
            p[name] = round(v) if isinstance(lo, int) and isinstance(hi, int) else v
        points.append(p)
    return points


def load_spec(path: str | Path, out_dir: str | Path | None = None) -> SweepSpec:
    """Read a sweep spec (TOML) and expand it into jobs. Raises ValueError naming the file and
    the key on unknown keys, wrong types, missing recordings or a spec without parameters."""
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"spec: {path} is not a file")
    with path.open("rb") as f:
        try:
            doc = tomllib.load(f)
        except tomllib.TOMLDecodeError as e:
            raise _err(path, f"not valid TOML: {e}") from None
    unknown = set(doc) - {"sweep", "grid", "search"}
    if unknown:
        raise _err(path, f"unknown table(s) {sorted(unknown)} (expected sweep, grid, search)")
    spec = doc.get("sweep")
    if not isinstance(spec, dict):
        raise _err(path, "missing [sweep] table")
    known = {"name", "kind", "base", "recordings", "metric", "maximize", "write_tracks"}
    unknown = set(spec) - known
    if unknown:
        raise _err(path, f"sweep: unknown key(s) {sorted(unknown)}")
    kind = spec.get("kind", "pipeline")
    if not isinstance(kind, str) or (kind not in JOB_KINDS and ":" not in kind):
        raise _err(path, f"sweep.kind: expected one of {JOB_KINDS} or 'module:function'")
    base = spec.get("base")
    if not isinstance(base, str):
        raise _err(path, "sweep.base: expected a preset name or a config path (string)")
    if (path.parent / base).exists():
        base = str((path.parent / base).resolve())
    if "grid" in doc and "search" in doc:
        raise _err(path, "give either [grid] or [search], not both")
    if "grid" in doc:
        points = _grid(path, doc["grid"])
    elif "search" in doc:
        points = _search(path, doc["search"])
    else:
        points = [{}]
    recordings = _recordings(spec, path)
    tracks_root = None
    if spec.get("write_tracks", False):
        tracks_root = Path(out_dir or ".").resolve() / "tracks"
    jobs = []
    for rec, truth in recordings:
        for p in points:
            jid = _job_id(kind, rec, truth, base, p)
            tdir = str(tracks_root / jid) if tracks_root is not None else None
            jobs.append(Job(jid, kind, rec, truth, base, dict(p), tdir))
    return SweepSpec(
        name=str(spec.get("name", path.stem)),
        path=path,
        jobs=jobs,
        parameters=list(points[0]),
        metric=str(spec.get("metric", "rmse")),
        maximize=bool(spec.get("maximize", False)),
    )
