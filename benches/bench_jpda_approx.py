"""Error and cost of the approximate JPDA marginals (loopy belief propagation, Williams & Lau,
IEEE Trans. AES 50(4), 2014; and the k most likely joint hypotheses by Murty's ranking, Cox &
Miller 1995) against the exact ones (EHM), on clusters where all run.

Clusters are built like a tracker's: `n` tracks on a square grid `spacing` metres apart, each
detected with P_D 0.9 at σ 0.25 m plus Poisson clutter, PDA weights N(z; x, S) P_D / λ inside a
99 % gate and 1 − P_D P_G for the miss (S = 2σ², λ = 0.125 m⁻²). Per size: max and mean
absolute error over all marginals and the time of each (same process, `_core.jpda_marginals`).

    PYTHONPATH=python python benches/bench_jpda_approx.py [--clusters 50] [--damping]

With --damping it also runs the same message passing in numpy (checked equal to the core's to
1e-9) without and with damping ν ← ½ν + ½ν_new, to tolerance 1e-13 in at most 5,000 sweeps:
the sweeps taken and the max error of both show whether the error is a lack of convergence
or the fixed point's own.
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


def lbp_numpy(w: np.ndarray, damping: float = 0.0) -> tuple[np.ndarray, int]:
    """Williams & Lau's iteration (as `_core.jpda_marginals(w, "lbp")`), dense, with damping."""
    w0, wd = w[:, 0], w[:, 1:]
    gated = wd > 0
    nu = gated.astype(float)
    sweep = 0
    while sweep < 5000:
        sweep += 1
        den = w0[:, None] + (wd * nu).sum(1, keepdims=True) - wd * nu
        mu = np.where(gated, wd / den, 0.0)
        new = np.where(gated, 1.0 / (1.0 + mu.sum(0, keepdims=True) - mu), 0.0)
        change = np.abs(new - nu).max(initial=0.0)
        nu = damping * nu + (1 - damping) * new
        if change <= 1e-13:
            break
    p = np.column_stack([w0, wd * nu])
    return p / p.sum(1, keepdims=True), sweep


def damping_check(rng: np.random.Generator, clusters: int) -> None:
    print("tracks spacing  sweeps  max |err| undamped  damped 0.5")
    for n, spacing in [(16, 1.0), (16, 0.5), (25, 0.5)]:
        sweeps, e0, e5 = 0, 0.0, 0.0
        for _ in range(clusters):
            w = np.ascontiguousarray(cluster(rng, n, spacing))
            exact = _core.jpda_marginals(w, "ehm")
            p0, k = lbp_numpy(w)
            assert np.abs(p0 - _core.jpda_marginals(w, "lbp")).max() < 1e-9
            p5, _ = lbp_numpy(w, 0.5)
            sweeps = max(sweeps, k)
            e0 = max(e0, np.abs(p0 - exact).max())
            e5 = max(e5, np.abs(p5 - exact).max())
        print(f"{n:6d} {spacing:7.1f} {sweeps:7d} {e0:18.4f} {e5:11.4f}", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--clusters", type=int, default=50)
    ap.add_argument("--damping", action="store_true", help="also the damping check")
    a = ap.parse_args()
    rng = np.random.default_rng(0)
    if a.damping:
        damping_check(np.random.default_rng(0), a.clusters)
    methods = [("lbp", 0), ("kbest", 100), ("kbest", 1000)]
    print("max |err| (mean |err|) and ms per cluster; EHM is exact")
    head = "".join(f"{m + (str(k) if k else ''):>22}" for m, k in methods)
    print(f"tracks spacing   EHM ms{head}")
    for n, spacing in [(4, 0.3), (9, 0.3), (9, 0.5), (16, 0.5), (16, 1.0), (25, 0.5)]:
        errs = {m: [] for m in methods}
        times = dict.fromkeys(methods, 0.0)
        t_e = 0.0
        for _ in range(a.clusters):
            w = np.ascontiguousarray(cluster(rng, n, spacing))
            t0 = time.perf_counter()
            exact = _core.jpda_marginals(w, "ehm")
            t_e += time.perf_counter() - t0
            for m in methods:
                t0 = time.perf_counter()
                approx = _core.jpda_marginals(w, m[0], m[1] or 1)
                times[m] += time.perf_counter() - t0
                errs[m].append(np.abs(exact - approx).ravel())
        k = a.clusters
        cells = ""
        for m in methods:
            e = np.concatenate(errs[m])
            cells += f"{e.max():8.4f} ({e.mean():7.1e}) {times[m] / k * 1e3:6.2f}"
        print(f"{n:6d} {spacing:7.1f} {t_e / k * 1e3:8.3f}{cells}", flush=True)


if __name__ == "__main__":
    main()
