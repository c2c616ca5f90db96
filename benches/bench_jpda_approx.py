"""Error and cost of the approximate JPDA marginals (loopy belief propagation, Williams & Lau,
IEEE Trans. AES 50(4), 2014) against the exact ones (EHM), on clusters where both run.

Clusters are built like a tracker's: `n` tracks on a square grid `spacing` metres apart, each
detected with P_D 0.9 at σ 0.25 m plus Poisson clutter, PDA weights N(z; x, S) P_D / λ inside a
99 % gate and 1 − P_D P_G for the miss (S = 2σ², λ = 0.125 m⁻²). Per size: max and mean
absolute error over all marginals, and the time of both (same process, `_core.jpda_marginals`).

    PYTHONPATH=python python benches/bench_jpda_approx.py [--clusters 50]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from usvfast import _core

SIGMA, PD, PG, LAM = 0.25, 0.9, 0.99, 0.125


def cluster(rng, n, spacing):
    side = int(np.ceil(np.sqrt(n)))
    x = np.column_stack([np.arange(n) % side, np.arange(n) // side]) * spacing
    seen = rng.random(n) < PD
    z = x[seen] + rng.normal(0, SIGMA, (seen.sum(), 2))
    lo, hi = x.min(0) - 1, x.max(0) + 1
    z = np.vstack([z, rng.uniform(lo, hi, (rng.poisson(LAM * np.prod(hi - lo) * 0.2), 2))])
    s = 2 * SIGMA**2
    d2 = ((x[:, None, :] - z[None, :, :]) ** 2).sum(-1) / s
    w = np.where(d2 <= _core.chi2_gate(PG, 2), PD / LAM * np.exp(-d2 / 2) / (2 * np.pi * s), 0)
    return np.column_stack([np.full(n, 1 - PD * PG), w])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--clusters", type=int, default=50)
    a = ap.parse_args()
    rng = np.random.default_rng(0)
    print("tracks spacing   max |err|  mean |err|   EHM ms   LBP ms  ratio")
    for n, spacing in [(4, 0.3), (9, 0.3), (9, 0.5), (16, 0.5), (16, 1.0), (25, 0.5)]:
        errs, t_e, t_l = [], 0.0, 0.0
        for _ in range(a.clusters):
            w = np.ascontiguousarray(cluster(rng, n, spacing))
            t0 = time.perf_counter()
            exact = _core.jpda_marginals(w, "ehm")
            t1 = time.perf_counter()
            approx = _core.jpda_marginals(w, "lbp")
            t2 = time.perf_counter()
            t_e, t_l = t_e + t1 - t0, t_l + t2 - t1
            errs.append(np.abs(exact - approx).ravel())
        e = np.concatenate(errs)
        k = a.clusters
        print(
            f"{n:6d} {spacing:7.1f} {e.max():11.4f} {e.mean():11.2e} {t_e / k * 1e3:8.3f} "
            f"{t_l / k * 1e3:8.3f} {t_e / t_l:6.1f}",
            flush=True,
        )


if __name__ == "__main__":
    main()
