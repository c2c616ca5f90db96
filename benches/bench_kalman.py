"""Batch Kalman filter + RTS smoother: usvfast vs filterpy vs Stone Soup vs a pure-Python loop.

A 10,000-measurement bearing sequence (2-state Wiener velocity, irregular dt, two sensors with
different R), the same input for everybody, one process. Prints µs per measurement (filter and
smoother separately where the peer allows) and the ratio to usvfast.

    python benches/bench_kalman.py [--n 10000] [--stonesoup-n 10000]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

from timing import best_of

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from usvfast.kalman import ConstantVelocity, kalman_filter

Q = 0.01**2
NOISES = np.array([[[0.7**2]], [[1.0**2]]])


def make_input(n: int, seed: int = 0):
    rng = np.random.default_rng(seed)
    times = np.round(1.7e9 + np.cumsum(rng.uniform(0.02, 0.3, n)), 6)
    idx = rng.integers(0, 2, n)
    z = (40.0 + 0.05 * (times - times[0]) + rng.normal(0, 0.8, n)).reshape(-1, 1)
    return times, z, idx, np.array([40.0, 0.0]), np.diag([10.0, 1.0])


def ours(times, z, idx, x0, p0, smooth=True):
    return kalman_filter(
        times,
        z,
        motion_model=ConstantVelocity(Q),
        measurement_matrix=[[1.0, 0.0]],
        measurement_noise=NOISES,
        sensor_index=idx,
        prior_state=x0,
        prior_covariance=p0,
        smooth=smooth,
    )


def pure_python(times, z, idx, x0, p0):
    """Hand-unrolled scalar 2-state KF + RTS in plain Python floats (the fastest Python peer)."""
    r = [NOISES[0, 0, 0], NOISES[1, 0, 0]]
    x, v = float(x0[0]), float(x0[1])
    pxx, pxv, pvv = float(p0[0, 0]), float(p0[0, 1]), float(p0[1, 1])
    zs, ts, ids = z[:, 0].tolist(), times.tolist(), idx.tolist()
    filt, pred = [], []
    t_prev = ts[0]
    t0 = time.perf_counter()
    for zi, t, s in zip(zs, ts, ids, strict=True):
        dt = t - t_prev
        t_prev = t
        x, v = x + dt * v, v
        pxx, pxv, pvv = (
            pxx + 2 * dt * pxv + dt * dt * pvv + Q * dt**3 / 3,
            pxv + dt * pvv + Q * dt * dt / 2,
            pvv + Q * dt,
        )
        pred.append((x, v, pxx, pxv, pvv))
        sv = pxx + r[s]
        kx, kv = pxx / sv, pxv / sv
        y = zi - x
        x, v = x + kx * y, v + kv * y
        pxx, pxv, pvv = pxx - kx * pxx, pxv - kx * pxv, pvv - kv * pxv
        filt.append((x, v, pxx, pxv, pvv))
    t1 = time.perf_counter()
    sx, sv_, sxx, sxv, svv = filt[-1]
    for k in range(len(filt) - 2, -1, -1):
        dt = ts[k + 1] - ts[k]
        fx, fv, fxx, fxv, fvv = filt[k]
        px, pv, pxx, pxv, pvv = pred[k + 1]
        det = pxx * pvv - pxv * pxv
        ixx, ixv, ivv = pvv / det, -pxv / det, pxx / det
        # C = P_f Fᵀ P_pred⁻¹ with F = [[1, dt], [0, 1]]
        a, b, c = fxx + dt * fxv, fxv, fxv + dt * fvv
        cxx, cxv = a * ixx + b * ixv, a * ixv + b * ivv
        cvx, cvv = c * ixx + fvv * ixv, c * ixv + fvv * ivv
        dx, dv = sx - px, sv_ - pv
        sx, sv_ = fx + cxx * dx + cxv * dv, fv + cvx * dx + cvv * dv
        exx, exv, evv = sxx - pxx, sxv - pxv, svv - pvv
        sxx = fxx + cxx * (cxx * exx + cxv * exv) + cxv * (cxx * exv + cxv * evv)
        sxv = fxv + cxx * (cvx * exx + cvv * exv) + cxv * (cvx * exv + cvv * evv)
        svv = fvv + cvx * (cvx * exx + cvv * exv) + cvv * (cvx * exv + cvv * evv)
    t2 = time.perf_counter()
    return t1 - t0, t2 - t1, sx


def filterpy_run(times, z, idx, x0, p0):
    """filterpy KalmanFilter + rts_smoother with F and Q built in numpy, as a user would."""
    from filterpy.kalman import KalmanFilter, rts_smoother

    kf = KalmanFilter(dim_x=2, dim_z=1)
    kf.x = x0.reshape(2, 1).copy()
    kf.P = p0.copy()
    kf.H = np.array([[1.0, 0.0]])
    xs, ps, fs, qs = [], [], [], []
    t0 = time.perf_counter()
    t_prev = times[0]
    for i, t in enumerate(times):
        dt = t - t_prev
        t_prev = t
        kf.F = np.array([[1.0, dt], [0.0, 1.0]])
        kf.Q = Q * np.array([[dt**3 / 3, dt**2 / 2], [dt**2 / 2, dt]])
        kf.predict()
        kf.update(z[i], R=NOISES[idx[i]])
        xs.append(kf.x.ravel().copy())
        ps.append(kf.P.copy())
        fs.append(kf.F)
        qs.append(kf.Q)
    t1 = time.perf_counter()
    # filterpy 2's rts_smoother takes Fs[k], Qs[k] as the step from k to k + 1.
    fs_next = np.array([*fs[1:], np.eye(2)])
    qs_next = np.array([*qs[1:], np.zeros((2, 2))])
    xs_s, _, _, _ = rts_smoother(np.array(xs), np.array(ps), fs_next, qs_next)
    t2 = time.perf_counter()
    return t1 - t0, t2 - t1, xs_s


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=10_000)
    ap.add_argument("--stonesoup-n", type=int, default=10_000)
    args = ap.parse_args()
    times, z, idx, x0, p0 = make_input(args.n)
    n = args.n

    t_both, _ = best_of(lambda: ours(times, z, idx, x0, p0), 20)
    t_filter, _ = best_of(lambda: ours(times, z, idx, x0, p0, smooth=False), 20)
    rows = [("usvfast (Rust, batch)", t_filter / n, (t_both - t_filter) / n, n)]

    from peers import stonesoup_kf_rts

    model = [ConstantVelocity(Q)]
    h = np.array([[1.0, 0.0]])
    fp_f, fp_s, ref = filterpy_run(times, z, idx, x0, p0)
    np.testing.assert_allclose(ours(times, z, idx, x0, p0).smoothed_states, ref, rtol=1e-9)
    rows.append(("filterpy (KalmanFilter + rts_smoother)", fp_f / n, fp_s / n, n))

    py_f, py_s, py_last = pure_python(times, z, idx, x0, p0)
    np.testing.assert_allclose(py_last, ref[0, 0], rtol=1e-6)
    rows.append(("pure-Python unrolled loop", py_f / n, py_s / n, n))

    ns = min(args.stonesoup_n, n)
    t0 = time.perf_counter()
    stonesoup_kf_rts(model, times[:ns], z[:ns], h, NOISES, idx[:ns], x0, p0)
    t_ss = time.perf_counter() - t0
    rows.append(("Stone Soup (predictor/updater/smoother)", t_ss / ns, float("nan"), ns))

    ours_total = t_both / n
    print(f"Kalman filter + RTS smoother, {n} measurements, 2-state Wiener velocity, two R's")
    head = ("implementation", "filter µs", "smooth µs", "total µs", "× usvfast")
    print(f"{head[0]:42s} " + " ".join(f"{h:>10s}" for h in head[1:]))
    for name, f, s, _ in rows:
        total = f if np.isnan(s) else f + s
        sm = "(incl.)" if np.isnan(s) else f"{s * 1e6:10.3f}"
        print(
            f"{name:42s} {f * 1e6:10.3f} {sm:>10s} {total * 1e6:10.3f} {total / ours_total:10.1f}"
        )


if __name__ == "__main__":
    main()
