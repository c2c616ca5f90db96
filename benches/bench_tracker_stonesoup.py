"""Tracker speed: usvfast vs Stone Soup on the same scenarios, in the same process.

The thesis's Code 5.7 configuration (CV q = 0.001, PDA P_D 0.85 / P_G 0.95, clutter 0.125,
multi-measurement initiator with a 0.3 Mahalanobis gate, 35-step / trace-1.5 deleters) is
built once in Stone Soup; usvfast's native tracker is built from those very components
(`usvfast.stonesoup.read_components` + `build_native`), and the drop-in wraps them too.
Reported: ms per scan in steady state (median over the second half of the scans), the ratio to
Stone Soup, and the final number of tracks (Stone Soup leaves duplicate tracks on some targets;
the drop-in reproduces them; the native option `initiate_in_gates=False` avoids them).

Cases: (a) 5 separated targets with clutter; (b) 20 separated targets (plain Stone Soup JPDA
enumerates all tracks jointly: capped); (c) 8 targets 0.3 m apart moving in parallel, and 20
clustered targets; (d) usvfast alone on 10 ... 10,000 separated targets.

    PYTHONPATH=python python benches/bench_tracker_stonesoup.py          # quick (~3 min)
    PYTHONPATH=python python benches/bench_tracker_stonesoup.py --full   # longer, 10k targets
"""

from __future__ import annotations

import argparse
import signal
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from usvfast import stonesoup as us

import ssharness as H


class Timeout(Exception):
    pass


def _alarm(signum, frame):
    raise Timeout


def steady(per_scan: list[float]) -> float:
    """Median ms per scan over the second half of the scans (the machine is shared: the
    median ignores the odd descheduled scan)."""
    a = np.asarray(per_scan)
    return float(np.median(a[len(a) // 2 :]) * 1e3) if len(a) else float("nan")


def duplicates(positions: np.ndarray, scenario) -> int:
    """Tracks beyond the first on the same target at the last scan: each track goes to its
    nearest live target within 1 m; duplicates = such tracks - distinct targets they hit.
    Meaningful for separated targets only (in a 0.5 m cluster "nearest" is ambiguous)."""
    truth = scenario.truth[-1]
    live = ~np.isnan(truth[:, 0])
    if not len(positions) or not live.any():
        return 0
    tpos = truth[live][:, [0, 2]]
    d = np.linalg.norm(positions[:, None, :] - tpos[None, :, :], axis=2)
    near = d.min(axis=1) <= 1.0
    hit = d.argmin(axis=1)[near]
    return int(near.sum() - len(set(hit.tolist())))


def _positions(tracks) -> np.ndarray:
    return np.array(
        [[float(t.state_vector[0, 0]), float(t.state_vector[2, 0])] for t in tracks]
    ).reshape(-1, 2)


def time_stonesoup(scenario, cfg: H.Code57, budget: float) -> dict:
    """Run Stone Soup scan by scan; stop when the budget (s) is spent, even mid-scan."""
    tracker, _ = H.build_stonesoup(cfg, detector=H.stonesoup_scans(scenario))
    it = iter(tracker)
    per, n_tracks = [], 0
    signal.signal(signal.SIGALRM, _alarm)
    t_start = time.perf_counter()
    signal.setitimer(signal.ITIMER_REAL, budget)
    aborted = None
    try:
        for _ in range(scenario.n_scans):
            t0 = time.perf_counter()
            _, tracks = next(it)
            per.append(time.perf_counter() - t0)
            n_tracks = len(tracks)
    except Timeout:
        aborted = (len(per), time.perf_counter() - t0, len(tracker.tracks))
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
    return {
        "ms": steady(per),
        "scans": len(per),
        "tracks": n_tracks,
        "dups": duplicates(_positions(tracker.tracks), scenario) if aborted is None else 0,
        "aborted": aborted,
        "total": time.perf_counter() - t_start,
    }


def native_tracker(cfg: H.Code57, scenario, initiate_in_gates: bool = True):
    """usvfast's native tracker built from the Stone Soup components of `cfg`."""
    from usvfast import tracking as tk

    tracker, _ = H.build_stonesoup(cfg)
    read = us.read_components(
        initiator=tracker.initiator,
        deleter=tracker.deleter,
        data_associator=tracker.data_associator,
        updater=tracker.updater,
        mixture=cfg.associator != "gnn",
    )
    h = np.array([[1.0, 0, 0, 0], [0, 0, 1.0, 0]])
    sensors = [tk.Sensor(h, s.noise) for s in scenario.sensors]
    return us.build_native(read, sensors, initiate_in_gates=initiate_in_gates)


def time_native(scenario, cfg: H.Code57, initiate_in_gates: bool = True) -> dict:
    tr = native_tracker(cfg, scenario, initiate_in_gates)
    per = []
    for t, z, s in scenario.scans():
        t0 = time.perf_counter()
        tr.step(t, z, s)
        per.append(time.perf_counter() - t0)
    final = tr.tracks
    return {
        "ms": steady(per),
        "tracks": len(final),
        "dups": duplicates(final.states[:, [0, 2]], scenario),
        "total": sum(per),
    }


def time_batch(scenario, cfg: H.Code57) -> float:
    """ms per scan of one `Tracker.run` call over the whole recording."""
    tr = native_tracker(cfg, scenario)
    counts = [len(z) for z in scenario.measurements]
    z = np.concatenate(scenario.measurements)
    s = np.concatenate(scenario.sensor_ids)
    idx = np.repeat(np.arange(scenario.n_scans), counts)
    t0 = time.perf_counter()
    tr.run(scenario.times, z, s, idx)
    return (time.perf_counter() - t0) / scenario.n_scans * 1e3


def time_dropin(scenario, cfg: H.Code57, hypotheses: bool = True) -> dict:
    tracker, _ = H.build_stonesoup(cfg)
    cls = us.MultiTargetTracker if cfg.associator == "gnn" else us.MultiTargetMixtureTracker
    d = cls(
        initiator=tracker.initiator,
        deleter=tracker.deleter,
        detector=H.stonesoup_scans(scenario),
        data_associator=tracker.data_associator,
        updater=tracker.updater,
        hypotheses=hypotheses,
    )
    per, n = [], 0
    it = iter(d)
    for _ in range(scenario.n_scans):
        t0 = time.perf_counter()
        _, tracks = next(it)
        per.append(time.perf_counter() - t0)
        n = len(tracks)
    return {"ms": steady(per), "tracks": n, "dups": duplicates(_positions(d.tracks), scenario)}


def fmt_ss(r: dict) -> str:
    if r["aborted"] is not None:
        k, dt, n = r["aborted"]
        head = f"{r['ms']:9.2f} ms" if r["scans"] > 1 else "     (n/a)"
        return f"{head}  ABORTED in scan {k} after {dt:.1f} s with {n} tracks"
    return f"{r['ms']:9.2f} ms  ({r['tracks']} tracks, {r['dups']} duplicates)"


def case(name: str, scenario, budget: float, plain: bool = True) -> None:
    cfg = H.Code57()
    print(
        f"\n({name}) {scenario.name}: {scenario.truth.shape[1]} targets, {scenario.n_scans} scans"
    )
    ours = time_native(scenario, cfg)
    ours_ng = time_native(scenario, cfg, initiate_in_gates=False)
    batch = time_batch(scenario, cfg)
    drop = time_dropin(scenario, cfg)
    drop_nh = time_dropin(scenario, cfg, hypotheses=False)
    rows = []
    refs = {}
    for label, assoc in (("Stone Soup JPDA", "jpda"), ("Stone Soup JPDAwithEHM", "ehm")):
        if assoc == "jpda" and not plain:
            print(f"  {label:32s}  skipped (brute-force enumeration cannot finish)")
            continue
        r = time_stonesoup(scenario, cfg.with_(associator=assoc), budget)
        refs[label] = r
        rows.append((label, r))
    for label, r in rows:
        print(f"  {label:32s} {fmt_ss(r)}")
    print(
        f"  {'usvfast native step()':32s} {ours['ms']:9.3f} ms  ({ours['tracks']} tracks, "
        f"{ours['dups']} duplicates)"
    )
    print(f"  {'usvfast native run() batch':32s} {batch:9.3f} ms")
    print(
        f"  {'usvfast native, initiate_in_gates=False':32s} {ours_ng['ms']:9.3f} ms  "
        f"({ours_ng['tracks']} tracks, {ours_ng['dups']} duplicates)"
    )
    print(
        f"  {'usvfast.stonesoup drop-in':32s} {drop['ms']:9.3f} ms  ({drop['tracks']} tracks, "
        f"{drop['dups']} duplicates)"
    )
    print(f"  {'drop-in, hypotheses=False':32s} {drop_nh['ms']:9.3f} ms")
    for label, r in refs.items():
        if r["aborted"] is None and np.isfinite(r["ms"]):
            print(
                f"  ratio {label} / native: {r['ms'] / ours['ms']:8.0f}x   "
                f"/ drop-in: {r['ms'] / drop['ms']:6.1f}x   tracks SS {r['tracks']} = drop-in "
                f"{drop['tracks']}: {r['tracks'] == drop['tracks']}"
            )


def scaling(sizes: list[int]) -> None:
    print("\n(d) usvfast native, separated targets (20 m grid), 2 clutter plots per scan")
    prev = None
    for n in sizes:
        sc = H.separated(n, seed=0, duration=10.0, clutter_rate=2.0)
        r = time_native(sc, H.Code57())
        per_target = r["ms"] / n * 1e3
        growth = "" if prev is None else f"  x{r['ms'] / prev:.1f} for x10 targets"
        prev = r["ms"]
        print(
            f"  {n:6d} targets: {r['ms']:9.3f} ms per scan ({per_target:6.2f} µs per target), "
            f"{r['tracks']} tracks{growth}"
        )


def joyride(path: str | None = None) -> None:
    """Real radar (238 scans): Stone Soup JPDA with the issue's anchor parameters vs the same
    configuration through the drop-in and the native run(), and the chosen native parameters."""
    from usvfast.datasets import load_joyride

    from conftest import SHARED_DATA

    path = path or str(SHARED_DATA / "joyride" / "joyride.mat")
    if not Path(path).is_file():
        print(f"\n(joyride) skipped: {path} not found")
        return
    rec = load_joyride(path)
    print(f"\n(joyride) real radar plots, {rec.n_scans} scans, 1-7 plots per scan")

    def per_scan(it) -> float:
        per = []
        it = iter(it)
        for _ in range(rec.n_scans):
            t0 = time.perf_counter()
            next(it)
            per.append(time.perf_counter() - t0)
        return float(np.mean(per) * 1e3)

    ss, _ = H.build_stonesoup(H.JOYRIDE_ANCHOR, detector=H.joyride_scans(rec, H.JOYRIDE_SIGMA))
    t_ss = per_scan(ss)
    comp, _ = H.build_stonesoup(H.JOYRIDE_ANCHOR)
    drop = us.MultiTargetMixtureTracker(
        initiator=comp.initiator,
        deleter=comp.deleter,
        detector=H.joyride_scans(rec, H.JOYRIDE_SIGMA),
        data_associator=comp.data_associator,
        updater=comp.updater,
    )
    t_drop = per_scan(drop)
    idx, plots = rec.scan_arrays()
    times = rec.times - rec.times[0]
    out = {}
    for label, params in (
        ("anchor", H.joyride_anchor_native_kwargs()),
        ("chosen", H.JOYRIDE_NATIVE),
    ):
        tr = H.joyride_native(**params)
        t0 = time.perf_counter()
        tr.run(times, plots, np.zeros(len(plots), np.int64), idx)
        out[label] = (time.perf_counter() - t0) / rec.n_scans * 1e3
    print(f"  {'Stone Soup JPDA (anchor)':32s} {t_ss:9.3f} ms per scan (mean)")
    print(f"  {'usvfast drop-in (anchor)':32s} {t_drop:9.3f} ms   {t_ss / t_drop:6.0f}x")
    for label in ("anchor", "chosen"):
        ms = out[label]
        print(f"  {f'usvfast native run() ({label})':32s} {ms:9.4f} ms   {t_ss / ms:6.0f}x")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--full", action="store_true", help="longer scenarios and 10k targets")
    args = ap.parse_args()
    dur = 80.0 if args.full else 40.0
    budget = 120.0 if args.full else 30.0
    case("a", H.separated(5, seed=0, duration=dur, clutter_rate=3.0), budget)
    case("b", H.separated(20, seed=0, duration=dur, clutter_rate=3.0), budget)
    case("c", H.parallel(8, spacing=0.3, seed=0, duration=dur), budget)
    case("c", H.clustered(20, seed=0, duration=dur), budget, plain=False)
    joyride()
    scaling([10, 100, 1000, 10000] if args.full else [10, 100, 1000])


if __name__ == "__main__":
    main()
