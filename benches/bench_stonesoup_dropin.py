"""The Stone Soup drop-in against Stone Soup's `MultiTargetMixtureTracker`, per scan, in one
process, on the thesis's Code 5.7 set-up (CV q = 0.001, PDA P_D 0.85 / P_G 0.95, clutter
0.125, multi-measurement initiator, 35-step / trace-1.5 deleters) over scenarios the parity
tests do not use (seeds 10-14): two sensors (LiDAR R 0.25² m² at 1 Hz, camera R 0.5² m²
every 1.5 s) with clutter, crossing targets, parallel targets within each other's gates, and
all of these at once (crossing + parallel targets seen by both sensors).

Both trackers consume the same prepared Detection objects; both run once untimed first
(imports, caches). Reported per scenario: ms per scan — wall-clock median over the second half
of the scans (as in benches/bench_tracker_stonesoup.py) and, in brackets, the mean process CPU
time over all scans, first scan included — and three ratios: wall-clock medians, CPU-time
medians (second half) and CPU-time means. On a loaded machine the wall clock counts the
milliseconds a process waits for a core: Stone Soup's 5-20 ms scans wait, the drop-in's
0.1 ms scans mostly do not, so the wall-clock ratio flatters the drop-in; the CPU-time
ratios are the fair ones. Also whether the drop-in gave Stone Soup's tracks (births, deaths,
states within 1e-6). The drop-in builds every Stone Soup object Stone Soup would (states and
JPDA hypotheses); the `hypotheses=False` column (wall clock) skips the hypotheses.

    PYTHONPATH=python python benches/bench_stonesoup_dropin.py [--seeds 10 11 12 13 14]
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


def per_scan(tracker, n: int) -> tuple[np.ndarray, list]:
    """(2, n) seconds per scan of iterating `tracker` n times — wall clock and this process's
    CPU time (which a descheduling by the other jobs of a shared machine does not inflate) —
    and the canonical records."""
    per: list[tuple[float, float]] = []

    def timed():
        it = iter(tracker)
        for _ in range(n):
            t0, c0 = time.perf_counter(), time.process_time()
            item = next(it)
            per.append((time.perf_counter() - t0, time.process_time() - c0))
            yield item

    records = H.run_tracker(timed())
    return np.asarray(per).T, records


class Timeout(Exception):
    pass


def _alarm(signum, frame):
    raise Timeout


def stonesoup(sc: H.Scenario, scans, budget: float = 0.0) -> tuple[np.ndarray, list] | None:
    """Stone Soup's run, or None when it did not finish within `budget` seconds (0: no
    limit): plain JPDA enumerates the joint hypotheses of all tracks, which explodes when
    duplicate tracks pile up on close targets."""
    tracker, _ = H.build_stonesoup(H.Code57(), detector=scans)
    if budget <= 0:
        return per_scan(tracker, sc.n_scans)
    signal.signal(signal.SIGALRM, _alarm)
    signal.setitimer(signal.ITIMER_REAL, budget)
    try:
        return per_scan(tracker, sc.n_scans)
    except Timeout:
        return None
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)


def dropin(sc: H.Scenario, scans, hypotheses: bool = True) -> tuple[np.ndarray, list]:
    c, _ = H.build_stonesoup(H.Code57())
    tracker = us.MultiTargetMixtureTracker(
        initiator=c.initiator,
        deleter=c.deleter,
        detector=scans,
        data_associator=c.data_associator,
        updater=c.updater,
        hypotheses=hypotheses,
    )
    return per_scan(tracker, sc.n_scans)


def median2(a: np.ndarray) -> float:
    return float(np.median(a[len(a) // 2 :]) * 1e3)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[10, 11, 12, 13, 14])
    ap.add_argument("--budget", type=float, default=60.0, help="s per Stone Soup run")
    args = ap.parse_args()
    warm = H.two_sensors(99)
    ws = H.stonesoup_scans(warm)
    stonesoup(warm, ws)
    dropin(warm, ws)
    print(
        f"{'scenario':30s} {'seed':>4s} {'scans':>5s} | {'Stone Soup ms':>13s} | "
        f"{'drop-in ms':>10s} | {'ratio':>6s} {'cpu':>6s} {'(cpu)':>6s} | {'no-hyp ratio':>12s} | "
        "same"
    )
    ratios, mean_ratios, cpu_ratios = [], [], []
    for seed in args.seeds:
        for sc in scenarios(seed):
            scans = H.stonesoup_scans(sc)
            got = stonesoup(sc, scans, args.budget)
            b, ours = dropin(sc, scans)
            if got is None:
                print(
                    f"{sc.name:30s} {seed:4d} {sc.n_scans:5d} | Stone Soup did not finish in "
                    f"{args.budget:.0f} s | drop-in {median2(b[0]):5.3f} ms per scan"
                )
                continue
            a, ref = got
            c, _ = dropin(sc, scans, hypotheses=False)
            same = H.compare_runs(ours, ref) == []
            (a, a_cpu), (b, b_cpu), c = a, b, c[0]
            r, rm = median2(a) / median2(b), a_cpu.mean() / b_cpu.mean()
            rc = median2(a_cpu) / median2(b_cpu)
            ratios.append(r)
            mean_ratios.append(rm)
            cpu_ratios.append(rc)
            print(
                f"{sc.name:30s} {seed:4d} {sc.n_scans:5d} | {median2(a):6.2f} "
                f"({a_cpu.mean() * 1e3:5.2f}) | {median2(b):5.3f} ({b_cpu.mean() * 1e3:5.3f})"
                f" | {r:6.0f} {rc:6.0f} {rm:6.0f} | {median2(a) / median2(c):12.0f} | {same}"
            )
    print("\nratio Stone Soup / drop-in per scan, min and geometric mean over the scenarios:")
    for label, rs in (
        ("wall clock, median of the second half", ratios),
        ("CPU time, median of the second half", cpu_ratios),
        ("CPU time, mean over all scans", mean_ratios),
    ):
        g = float(np.exp(np.mean(np.log(rs))))
        print(f"  {label:40s} min {min(rs):5.0f}x  geometric mean {g:5.0f}x")


if __name__ == "__main__":
    main()
