"""How often each ANIS band holds a seed's float ANIS on recordings nothing was chosen on: the
plain gated χ² band (independent samples) against the band corrected for NIS correlated
within tracks (`usvfast.metrics.consistency`, `variance_factor`), with a reading fixed in
advance.

    python benches/anis_band_fresh.py --work DIR

Protocol (declared and committed before any of its runs). Ten fresh seeds, 18-27, never run
through the pipeline before: each `usvfast simulate --seed S --duration 30`, then one `usvfast
run` with the simulator's template as it stands when this is run (nothing chosen on these
seeds, before or after). Per seed, from metrics.json's floats group: the ANIS, the plain
gated band and whether it holds the ANIS, the variance factor f and whether the corrected band
holds it. A calibrated 95 % band misses two or more of ten seeds with probability 8.6 %.
Reading, fixed now: if the corrected band holds at least 9 of the 10 and the plain band fewer,
the corrected band is taken as the calibrated reading of "ANIS inside its 95 % χ² band" for
the NIS of one recording; otherwise it is not. The result is reported as it comes; no seed is
added or dropped.

Result (run once after the protocol's commit, the template with `fix_quality_std = [[5,
0.05]]`):

| seed | float ANIS | plain band | inside | f | corrected band | inside |
| --- | --- | --- | --- | --- | --- | --- |
| 18 | 1.703 | [1.773, 2.045] | False | 1.68 | [1.735, 2.087] | False |
| 19 | 1.795 | [1.752, 2.068] | True | 1.76 | [1.703, 2.122] | True |
| 20 | 1.937 | [1.783, 2.035] | True | 1.66 | [1.749, 2.072] | True |
| 21 | 1.738 | [1.761, 2.059] | False | 1.72 | [1.717, 2.107] | True |
| 22 | 2.103 | [1.768, 2.051] | False | 1.85 | [1.719, 2.105] | True |
| 23 | 1.966 | [1.759, 2.060] | True | 1.51 | [1.727, 2.096] | True |
| 24 | 2.009 | [1.742, 2.079] | True | 1.79 | [1.688, 2.139] | True |
| 25 | 1.847 | [1.768, 2.051] | True | 1.58 | [1.733, 2.089] | True |
| 26 | 1.816 | [1.793, 2.024] | True | 2.04 | [1.745, 2.076] | True |
| 27 | 1.834 | [1.747, 2.074] | True | 1.65 | [1.703, 2.122] | True |

plain band: 7 / 10; corrected band: 9 / 10: the corrected band IS taken as the calibrated one.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from demo_detector_heldout import grid_runs

WEIGHTS = Path(__file__).resolve().parents[1] / "python/usvfast/data/models/harbour-demo.onnx"
FRESH_SEEDS = tuple(range(18, 28))


def main(argv: list[str] | None = None) -> None:
    """Simulate, run and tabulate (module doc)."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--work", type=Path, required=True, help="recordings and runs go here")
    args = ap.parse_args(argv)
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    print("| seed | float ANIS | plain band | inside | f | corrected band | inside |")
    print("| --- | --- | --- | --- | --- | --- | --- |")
    plain = corrected = 0
    for seed, _, out in grid_runs(
        args.work, list(FRESH_SEEDS), [None], WEIGHTS, lambda _: "template", lambda *_: []
    ):
        a = json.loads((out / "metrics.json").read_text())["groups"]["floats"]["anis"]
        plain += a["inside"]
        corrected += a["corrected_inside"]
        print(
            f"| {seed} | {a['mean']:.3f} | [{a['lower']:.3f}, {a['upper']:.3f}] | {a['inside']} "
            f"| {a['variance_factor']:.2f} | [{a['corrected_lower']:.3f}, "
            f"{a['corrected_upper']:.3f}] | {a['corrected_inside']} |",
            flush=True,
        )
    n = len(FRESH_SEEDS)
    print(f"\nplain band: {plain} / {n}; corrected band: {corrected} / {n}")
    taken = corrected >= 9 and plain < corrected
    print(f"reading: the corrected band {'IS' if taken else 'is NOT'} taken as the calibrated one")


if __name__ == "__main__":
    main()
