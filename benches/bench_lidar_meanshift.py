"""Mean shift: Rust flat-kernel mean shift vs scikit-learn's MeanShift, same input, one process.

500 buffered 2-D points (8 floating objects seen over four frames + 10 % surface clutter,
metres), bandwidth 2 m, cluster_all=False, with and without bin seeding. Checks that both
give the same centres and labels, prints best-of-N times and the ratios.

    python benches/bench_lidar_meanshift.py [--points 500] [--repeat 3]
"""

from __future__ import annotations

import argparse

import numpy as np
from sklearn.cluster import MeanShift

from usvfast.lidar import mean_shift

from timing import best_of


def buffered_detections(n: int, k: int = 8, seed: int = 7) -> np.ndarray:
    rng = np.random.default_rng(seed)
    centres = rng.uniform(-9, 9, (k, 2))
    clutter = n // 10
    objects = centres[np.arange(n - clutter) % k] + rng.normal(0, 0.15, (n - clutter, 2))
    return np.vstack([objects, rng.uniform(-10, 10, (clutter, 2))])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points", type=int, default=500)
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    x = buffered_detections(args.points)
    print(f"mean shift, {len(x)} points, bandwidth 2 m, cluster_all=False")
    for bin_seeding in (False, True):
        kw = {"bandwidth": 2.0, "cluster_all": False, "bin_seeding": bin_seeding}
        t_ours, (centers, labels) = best_of(lambda kw=kw: mean_shift(x, **kw), args.repeat * 20)
        t_sk, model = best_of(lambda kw=kw: MeanShift(**kw).fit(x), args.repeat)
        np.testing.assert_allclose(centers, model.cluster_centers_, atol=1e-9)
        np.testing.assert_array_equal(labels, model.labels_)
        print(
            f"  bin_seeding={bin_seeding!s:5}  {len(centers):3d} clusters  "
            f"rust {t_ours * 1e3:8.3f} ms   sklearn {t_sk * 1e3:8.1f} ms   "
            f"{t_sk / t_ours:8.0f}x"
        )


if __name__ == "__main__":
    main()
