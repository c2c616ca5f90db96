"""usvfast.geodesy vs pymap3d on the same 1,000,000 random points, in one process.

    PYTHONPATH=python python benches/bench_geodesy.py [--n 1000000] [--repeat 3]

pymap3d is given numpy arrays, so it runs vectorised; the best of `repeat` runs is reported.
"""

from __future__ import annotations

import argparse

import numpy as np
import pymap3d

from usvfast import geodesy

from timing import best_of


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--n", type=int, default=1_000_000)
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    rng = np.random.default_rng(0)
    lat = np.degrees(np.arcsin(rng.uniform(-1, 1, args.n)))
    lon = rng.uniform(-180, 180, args.n)
    alt = rng.uniform(-1000, 100_000, args.n)
    x, y, z = pymap3d.geodetic2ecef(lat, lon, alt)
    # Local-frame cases: points within ~50 km of one origin.
    lat0, lon0, h0 = 59.9, 10.7, 20.0
    nlat = lat0 + rng.uniform(-0.4, 0.4, args.n)
    nlon = lon0 + rng.uniform(-0.8, 0.8, args.n)
    nalt = rng.uniform(-10, 100, args.n)
    n, e, d = pymap3d.geodetic2ned(nlat, nlon, nalt, lat0, lon0, h0)
    cases = [
        ("geodetic2ecef", (lat, lon, alt)),
        ("ecef2geodetic", (x, y, z)),
        ("geodetic2ned", (nlat, nlon, nalt, lat0, lon0, h0)),
        ("ned2geodetic", (n, e, d, lat0, lon0, h0)),
        ("geodetic2enu", (nlat, nlon, nalt, lat0, lon0, h0)),
        ("enu2geodetic", (e, n, -d, lat0, lon0, h0)),
    ]
    print(f"{args.n:,} points, best of {args.repeat}")
    print(f"{'function':16s} {'usvfast':>10s} {'pymap3d':>10s} {'ratio':>7s} {'max diff':>10s}")
    for name, a in cases:
        t_ours, ours = best_of(lambda: getattr(geodesy, name)(*a), args.repeat)  # noqa: B023
        t_peer, peer = best_of(lambda: getattr(pymap3d, name)(*a), args.repeat)  # noqa: B023
        # Largest difference in the third output (metres) as a sanity check.
        diff = float(np.max(np.abs(np.asarray(ours[2]) - np.asarray(peer[2]))))
        print(
            f"{name:16s} {t_ours * 1e3:8.1f}ms {t_peer * 1e3:8.1f}ms "
            f"{t_peer / t_ours:6.1f}x {diff:10.2e}"
        )


if __name__ == "__main__":
    main()
