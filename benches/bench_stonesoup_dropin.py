"""The Stone Soup drop-in against Stone Soup's `MultiTargetMixtureTracker`, per scan, in one
process, on the thesis's Code 5.7 set-up (CV q = 0.001, PDA P_D 0.85 / P_G 0.95, clutter
0.125, multi-measurement initiator, 35-step / trace-1.5 deleters) over scenarios the parity
tests do not use (seeds 10-14): two sensors (LiDAR R 0.25² m² at 1 Hz, camera R 0.5² m²
every 1.5 s) with clutter, crossing targets, parallel targets within each other's gates, and
all of these at once (crossing + parallel targets seen by both sensors).

Both trackers consume the same prepared Detection objects; both run once untimed first
(imports, caches). The drop-in builds a track's Stone Soup states (and their JPDA hypotheses)
when they are first read, so three use patterns are timed. Per scenario: ms per scan of
`next(tracker)`, CPU-time median over the second half of the scans and, in brackets, the mean
over all scans (first scan included); then the ratios Stone Soup / drop-in:
  wall, cpu, mean — `next` alone: wall-clock and CPU medians (second half), CPU means;
  read — `next` plus reading every track's newest state and its hypothesis each scan (what a
         streaming user does; CPU medians, second half);
  all  — the whole run's CPU time, every state of every track read (so built) at the end;
  no-hyp — as `read` with `hypotheses=False` (no JPDA hypothesis objects).
On a loaded machine the wall clock counts the milliseconds a process waits for a core: Stone
Soup's 5-20 ms scans wait, the drop-in's 0.05 ms scans mostly do not, so the wall-clock ratio
flatters the drop-in; the CPU-time ratios are the fair ones. `same`: whether the drop-in gave
Stone Soup's tracks (births, deaths, states within 1e-6), lazily and read every scan.

    PYTHONPATH=python python benches/bench_stonesoup_dropin.py [--seeds 10 11 12 13 14]
"""

from __future__ import annotations

import argparse
import gc
import signal
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from usvfast import stonesoup as us

import ssharness as H


def crossing_and_parallel(seed: int, duration: float = 30.0) -> H.Scenario:
    """Two targets crossing, two moving side by side 0.4 m apart, one appearing late, seen by
    the LiDAR and the camera with clutter from both."""
    x0 = np.array(
        [
            [0.0, 0.2, 0.0, 0.2],
            [6.0, 0.0, 0.0, 0.2],
            [0.0, 0.15, 10.0, 0.02],
            [0.0, 0.15, 10.4, 0.02],
            [6.0, -0.2, 6.0, -0.2],
        ]
    )
    life = np.array([[0.0, np.inf]] * 4 + [[8.0, np.inf]])
    return H.simulate(
        "crossing+parallel, 2 sensors",
        x0,
        sensors=[H.LIDAR, H.CAMERA],
        duration=duration,
        seed=seed,
        clutter_rate=1.0,
        lifetimes=life,
    )


def scenarios(seed: int) -> list[H.Scenario]:
    return [
        H.two_sensors(seed),
        H.crossing(seed),
        H.parallel(4, seed=seed),
        crossing_and_parallel(seed),
    ]


def read_states(tracks) -> None:
    """What a streaming user reads each scan: every track's newest state and its hypothesis."""
    for track in tracks:
        state = track.state
        getattr(state, "hypothesis", None)


def per_scan(tracker, n: int, read: bool = False) -> tuple[np.ndarray, list, float]:
    """(3, n) seconds per scan of iterating `tracker` n times — wall clock and this process's
    CPU time (which a descheduling by the other jobs of a shared machine does not inflate) of
    `next`, and the CPU time of `read_states` on its tracks when `read` (else 0) — the
    canonical records, and the CPU seconds of recording them at the end (reading every
    state of every track: where the drop-in builds what nobody read before)."""
    per: list[tuple[float, float, float]] = []

    def timed():
        it = iter(tracker)
        for _ in range(n):
            t0, c0 = time.perf_counter(), time.process_time()
            item = next(it)
            t1, c1 = time.perf_counter(), time.process_time()
            if read:
                read_states(item[1])
            per.append((t1 - t0, c1 - c0, time.process_time() - c1))
            yield item

    gc.collect()  # no collection of an earlier run's garbage inside this one's timing
    c0 = time.process_time()
    records = H.run_tracker(timed())
    total = time.process_time() - c0
    per_a = np.asarray(per).T
    return per_a, records, total - per_a[1].sum() - per_a[2].sum()


class Timeout(Exception):
    pass


def _alarm(signum, frame):
    raise Timeout


def stonesoup(sc: H.Scenario, scans, budget: float = 0.0):
    """Stone Soup's run (see `per_scan`, with `read_states`), or None when it did not finish
    within `budget` seconds (0: no limit): plain JPDA enumerates the joint hypotheses of all
    tracks, which explodes when duplicate tracks pile up on close targets."""
    tracker, _ = H.build_stonesoup(H.Code57(), detector=scans)
    if budget <= 0:
        return per_scan(tracker, sc.n_scans, read=True)
    signal.signal(signal.SIGALRM, _alarm)
    signal.setitimer(signal.ITIMER_REAL, budget)
    try:
        return per_scan(tracker, sc.n_scans, read=True)
    except Timeout:
        return None
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)


def dropin(sc: H.Scenario, scans, hypotheses: bool = True, read: bool = False):
    c, _ = H.build_stonesoup(H.Code57())
    tracker = us.MultiTargetMixtureTracker(
        initiator=c.initiator,
        deleter=c.deleter,
        detector=scans,
        data_associator=c.data_associator,
        updater=c.updater,
        hypotheses=hypotheses,
    )
    return per_scan(tracker, sc.n_scans, read=read)


def median2(a: np.ndarray) -> float:
    return float(np.median(a[len(a) // 2 :]) * 1e3)


def geo(rs: list[float]) -> float:
    return float(np.exp(np.mean(np.log(rs))))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[10, 11, 12, 13, 14])
    ap.add_argument("--budget", type=float, default=60.0, help="s per Stone Soup run")
    args = ap.parse_args()
    warm = H.two_sensors(99)
    ws = H.stonesoup_scans(warm)
    stonesoup(warm, ws)
    dropin(warm, ws)
    dropin(warm, ws, read=True)
    print(
        f"{'scenario':28s} {'seed':>4s} {'scans':>5s} | {'Stone Soup ms':>13s} | "
        f"{'drop-in ms':>13s} | {'wall':>5s} {'cpu':>5s} {'mean':>5s} | {'read':>5s} "
        f"{'all':>5s} | {'no-hyp':>6s} | same"
    )
    cols: dict[str, list[float]] = {k: [] for k in ("wall", "cpu", "mean", "read", "all", "nohyp")}
    for seed in args.seeds:
        for sc in scenarios(seed):
            scans = H.stonesoup_scans(sc)
            got = stonesoup(sc, scans, args.budget)
            b, ours, b_rec = dropin(sc, scans)
            if got is None:
                print(
                    f"{sc.name:28s} {seed:4d} {sc.n_scans:5d} | Stone Soup did not finish in "
                    f"{args.budget:.0f} s | drop-in {median2(b[1]):5.3f} ms CPU per scan"
                )
                continue
            a, ref, a_rec = got
            r, ours_read, _ = dropin(sc, scans, read=True)
            c, _, _ = dropin(sc, scans, hypotheses=False, read=True)
            same = all(H.compare_runs(x, ref) == [] for x in (ours, ours_read))
            row = {
                "wall": median2(a[0]) / median2(b[0]),
                "cpu": median2(a[1]) / median2(b[1]),
                "mean": a[1].mean() / b[1].mean(),
                "read": median2(a[1] + a[2]) / median2(r[1] + r[2]),
                "all": (a[1].sum() + a_rec) / (b[1].sum() + b_rec),
                "nohyp": median2(a[1] + a[2]) / median2(c[1] + c[2]),
            }
            for k, v in row.items():
                cols[k].append(v)
            print(
                f"{sc.name:28s} {seed:4d} {sc.n_scans:5d} | {median2(a[1]):6.2f} "
                f"({a[1].mean() * 1e3:5.2f}) | {median2(b[1]):5.3f} ({b[1].mean() * 1e3:5.3f})"
                f" | {row['wall']:5.0f} {row['cpu']:5.0f} {row['mean']:5.0f} | "
                f"{row['read']:5.0f} {row['all']:5.0f} | {row['nohyp']:6.0f} | {same}"
            )
    print("\nratio Stone Soup / drop-in, min, max and geometric mean over the scenarios:")
    labels = {
        "wall": "per scan, wall clock, median of the second half",
        "cpu": "per scan, CPU time, median of the second half",
        "mean": "per scan, CPU time, mean over all scans",
        "read": "per scan + reading each track's state, CPU median",
        "all": "whole run + every state of every track built, CPU",
        "nohyp": "as 'read' with hypotheses=False",
    }
    for k, label in labels.items():
        rs = cols[k]
        print(
            f"  {label:52s} min {min(rs):5.0f}x  max {max(rs):5.0f}x  geometric mean "
            f"{geo(rs):5.0f}x"
        )


if __name__ == "__main__":
    main()
