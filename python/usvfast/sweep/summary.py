"""What a person reads after a sweep: the best parameter sets per recording, metric-vs-parameter
plots, and the Pareto front of accuracy against speed."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from usvfast._validate import as_float_array, instance, integer

SPEED_COLUMNS = ("metric.ms_per_scan", "wall_s")


def param_columns(table: pd.DataFrame) -> list[str]:
    """The `param.*` columns of a sweep table."""
    instance("table", table, pd.DataFrame)
    return [c for c in table.columns if c.startswith("param.")]


def best_rows(table: pd.DataFrame, metric: str, maximize: bool = False, n: int = 5):
    """The `n` best successful jobs per recording by `metric` (column `metric.<metric>`)."""
    instance("table", table, pd.DataFrame)
    instance("metric", metric, str)
    n = integer("n", n, low=0)
    col = f"metric.{metric}"
    # pandas' stubs type a boolean-masked frame loosely: the frames here are Any
    frame: Any = table
    ok: Any = frame[(frame["status"] == "ok") & frame.get(col, pd.Series(dtype=float)).notna()]
    if col not in ok:
        return ok.head(0)
    ranked = ok.sort_values(col, ascending=not maximize)
    return ranked.groupby("recording", sort=False).head(n)


def pareto_front(accuracy: np.ndarray, cost: np.ndarray) -> np.ndarray:
    """Indices of the points no other point beats on both (lower accuracy error, lower cost),
    sorted by cost; accuracy and cost are (n,) each (a NaN accuracy is never on the front).
    Raises ValueError naming them when their shapes differ."""
    accuracy = as_float_array("accuracy", accuracy, ndim=1, finite=False)
    cost = as_float_array("cost", cost, ndim=1, finite=False)
    if accuracy.shape != cost.shape:
        raise ValueError(
            f"accuracy, cost: expected two (n,) arrays, got {accuracy.shape} and {cost.shape}"
        )
    order = np.lexsort((accuracy, cost))
    front, best = [], np.inf
    for i in order:
        if accuracy[i] < best:
            front.append(i)
            best = accuracy[i]
    return np.array(front, dtype=np.int64)


def write_plots(table: pd.DataFrame, out_dir: Path, metric: str, maximize: bool = False):
    """`metric_vs_<param>.png` per varied parameter (one line per recording, the best value
    over the other parameters) and `pareto.png` (metric vs speed, front highlighted).
    Returns the paths written."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    col = f"metric.{metric}"
    ok: Any = table[(table["status"] == "ok")]
    if col not in ok or ok[col].notna().sum() == 0:
        return []
    ok = ok[ok[col].notna()]
    paths = []
    agg = "max" if maximize else "min"
    for p in param_columns(ok):
        if ok[p].nunique() < 2 or not pd.api.types.is_numeric_dtype(ok[p]):
            continue
        fig, ax = plt.subplots(figsize=(6, 4), constrained_layout=True)
        for rec, g in ok.groupby("recording"):
            line = g.groupby(p)[col].agg(agg)
            ax.plot(line.index, line.values, marker="o", label=Path(str(rec)).name)
        ax.set_xlabel(p.removeprefix("param."))
        ax.set_ylabel(f"{metric} ({agg} over the other parameters)")
        ax.set_title(f"{metric} vs {p.removeprefix('param.')}")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
        path = out_dir / f"{metric}_vs_{p.removeprefix('param.')}.png"
        fig.savefig(path, dpi=110)
        plt.close(fig)
        paths.append(path)
    speed = next((c for c in SPEED_COLUMNS if c in ok and ok[c].notna().all()), None)
    if speed is not None:
        acc = ok[col].to_numpy(float) * (-1 if maximize else 1)
        cost = ok[speed].to_numpy(float)
        front = pareto_front(acc, cost)
        fig, ax = plt.subplots(figsize=(6, 4), constrained_layout=True)
        ax.scatter(cost, ok[col], s=14, color="0.6", label="jobs")
        ax.plot(cost[front], ok[col].to_numpy()[front], "o-", color="C3", label="Pareto front")
        unit = "ms per scan" if speed == "metric.ms_per_scan" else "s per job"
        ax.set_xlabel(f"{speed.split('.')[-1]} ({unit})")
        ax.set_ylabel(metric)
        ax.set_title(f"accuracy vs speed ({len(ok)} jobs)")
        ax.grid(alpha=0.3)
        ax.legend()
        path = out_dir / "pareto.png"
        fig.savefig(path, dpi=110)
        plt.close(fig)
        paths.append(path)
    return paths
