"""Tables of the leave-one-video-out detection evaluation (:mod:`usvfast.shore.evaluate_det`):
Bloisi et al.'s Tables I–II layout and where the errors are (:mod:`usvfast.shore.errors`)."""

from __future__ import annotations

from rich.console import Console
from rich.table import Table


def print_tables(results: dict, console: Console | None = None) -> None:
    """Tables I–II layout: video, detector, filters, horizon, TPR, FAR, counts, size."""
    console = console or Console(width=140)
    t = Table(title="Detection, MarDCT leave one video out (IoU ≥ 0.5)")
    for col in ("video", "detector", "filters", "horizon", "TPR", "FAR", "TP", "FP", "FN", "size"):
        t.add_column(col)
    for v, e in results.items():
        for r in e["rows"]:
            t.add_row(
                v,
                r["detector"],
                r["filters"] or "-",
                "YES" if r["horizon"] else "NO",
                f"{r['tpr']:.3f}",
                f"{r['far']:.3f}",
                str(r["tp"]),
                str(r["fp"]),
                str(r["fn"]),
                f"{e['size'][0]}×{e['size'][1]}",
            )
    console.print(t)


def print_breakdown(results: dict, console: Console | None = None) -> None:
    """Where each row's errors are (:mod:`usvfast.shore.errors`): FP mislocalised (IoU
    0.1–0.5 with an annotated box), duplicate, pure false; FN mislocalised, covered by a
    box claimed elsewhere, missed; median area ratio (detection / annotated) and IoU of the
    mislocalised pairs."""
    console = console or Console(width=160)
    t = Table(
        title="Errors by cause (FP = mislocalised + duplicate + false; FN = mis + cov + missed)"
    )
    cols = ("video", "detector", "filters", "hz", "TP", "FP mis", "FP dup", "FP false")
    for col in (*cols, "FN mis", "FN cov", "FN missed", "area ×", "IoU"):
        t.add_column(col)
    for v, e in results.items():
        for r in e["rows"]:
            b = r["errors"]
            t.add_row(
                v,
                r["detector"],
                r["filters"] or "-",
                "YES" if r["horizon"] else "NO",
                *(
                    str(b[k])
                    for k in (
                        "tp",
                        "fp_mislocalised",
                        "fp_duplicate",
                        "fp_false",
                        "fn_mislocalised",
                        "fn_covered",
                        "fn_missed",
                    )
                ),
                f"{b['mislocalised_area_ratio']:.2f}",
                f"{b['mislocalised_iou']:.2f}",
            )
    console.print(t)
