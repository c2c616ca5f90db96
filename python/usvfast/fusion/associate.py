"""Radar track ↔ AIS target association over a sliding window, and fusion of the pair.

Two tests share one sliding-window associator with hysteresis and a one-to-one assignment:

* :class:`JCost` — the radar/AIS paper's §1.3 confidence (eqs. 1–4), with absolute
  differences: over the last N paired samples, J = k1·mean|Δp| + k2·mean|ΔV| + k3·mean|Δθ|
  (position metres, speed m/s, course degrees); the same target when J < J_set. (The paper
  sums over N; the mean keeps J_set independent of N.)
* :class:`Chi2Test` — the track-to-track test: the state difference Δx = x_r − x_a of the
  radar track and the AIS target with S = P_r + P_a (independent errors), summed over the
  window: D = Σ Δxᵀ S⁻¹ Δx ~ χ²(4N) for the same target; accepted when D < χ²₄N(p_gate).

Hysteresis: a new pair needs a full window and a normalised cost (J / J_set, or D /
χ²₄N(p_gate)) below 1; an existing pair is kept while its cost stays below `release`
(> 1) and both sides exist, so a decoy passing close cannot steal an identity and a
separating pair lets go. New pairs are assigned one-to-one by minimum total cost
(`scipy.optimize.linear_sum_assignment`).

§1.2 radar identity (:func:`same_object`): a track's position predicted t_d ahead with its
velocity, a later plot within radius R is the same object.

Fusion of an associated pair: :func:`covariance_intersection` (ω minimising the determinant
of the fused covariance), which is consistent whatever the unknown correlation of the two.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike
from scipy.optimize import linear_sum_assignment, minimize_scalar
from scipy.stats import chi2

from usvfast._validate import as_float_array

__all__ = [
    "Chi2Test",
    "JCost",
    "WindowAssociator",
    "covariance_intersection",
    "same_object",
]


def _positive(name: str, value: float) -> float:
    v = float(value)
    if not (math.isfinite(v) and v > 0):
        raise ValueError(f"{name}: must be finite and > 0, got {value!r}")
    return v


@dataclass(frozen=True)
class JCost:
    """The paper's confidence J (eqs. 1–4) with absolute differences, per unit of each term.

    k1 (1/m), k2 (1/(m/s)), k3 (1/deg); j_set: accept threshold of J; release: an existing
    pair breaks when J > release·j_set; min_speed (m/s): Δθ counts only when both speeds
    exceed it (a slow target has no defined course). Defaults (chosen on Joyride with
    generated AIS, docs/vts.md): a mean position error of 50 m, a speed error of 5 m/s and a
    course error of 90° each add 1 to J; J_set = 2.5, released above 1.6·J_set = 4. On
    Joyride the true pair's 8-scan J has median 1.3, 95th percentile 2.6 and maximum 3.0;
    the closest wrong pair never goes below 3.3."""

    k1: float = 0.02
    k2: float = 0.2
    k3: float = 1.0 / 90.0
    j_set: float = 2.5
    release: float = 1.6
    min_speed: float = 2.0

    def __post_init__(self) -> None:
        for name in ("k1", "k2", "k3", "j_set", "min_speed"):
            _positive(name, getattr(self, name))
        if not _positive("release", self.release) >= 1.0:
            raise ValueError(f"release: must be >= 1, got {self.release!r}")

    def sample(self, xr: np.ndarray, pr: np.ndarray, xa: np.ndarray, pa: np.ndarray) -> Any:
        """Per-sample terms (|Δp| m, |ΔV| m/s, |Δθ| deg) of one radar/AIS state pair."""
        dp = math.hypot(xr[0] - xa[0], xr[2] - xa[2])
        vr, va = math.hypot(xr[1], xr[3]), math.hypot(xa[1], xa[3])
        dth = 0.0
        if vr > self.min_speed and va > self.min_speed:
            d = math.atan2(xr[3], xr[1]) - math.atan2(xa[3], xa[1])
            dth = abs(math.degrees(math.atan2(math.sin(d), math.cos(d))))
        return (dp, abs(vr - va), dth)

    def cost(self, samples: ArrayLike) -> float:
        """J / J_set over the window's samples."""
        s = np.asarray(samples, dtype=float)
        j = self.k1 * s[:, 0].mean() + self.k2 * s[:, 1].mean() + self.k3 * s[:, 2].mean()
        return float(j / self.j_set)


@dataclass(frozen=True)
class Chi2Test:
    """χ² track-to-track test over the window: accept when D < χ²₄N(p_gate), release when
    D > χ²₄N(p_release). Defaults 0.99 and 0.9999."""

    p_gate: float = 0.99
    p_release: float = 0.9999

    def __post_init__(self) -> None:
        if not (0.0 < self.p_gate <= self.p_release < 1.0):
            raise ValueError(
                f"p_gate, p_release: need 0 < p_gate <= p_release < 1, got "
                f"{self.p_gate!r}, {self.p_release!r}"
            )

    @property
    def release(self) -> float:
        """Not used directly: the release threshold depends on the window length."""
        return math.inf

    def sample(self, xr: np.ndarray, pr: np.ndarray, xa: np.ndarray, pa: np.ndarray) -> Any:
        """Δxᵀ (P_r + P_a)⁻¹ Δx of one pair (4 degrees of freedom)."""
        d = xr - xa
        return float(d @ np.linalg.solve(pr + pa, d))

    def cost(self, samples: Any) -> float:
        """D / χ²₄N(p_gate) over the window's samples."""
        n = len(samples)
        return float(np.sum(samples) / chi2.ppf(self.p_gate, 4 * n))

    def release_ratio(self, n: int) -> float:
        """χ²₄N(p_release) / χ²₄N(p_gate): the release threshold in units of the cost."""
        return float(chi2.ppf(self.p_release, 4 * n) / chi2.ppf(self.p_gate, 4 * n))


class WindowAssociator:
    """Sliding-window radar ↔ AIS association with hysteresis (see the module docstring).

    method: :class:`JCost` or :class:`Chi2Test`; window: N paired samples (default 8, ~20 s
    of 2.5 s radar scans); gate_m: pairs farther apart than this (m) get no sample and their
    window is cleared. Call :meth:`update` once per radar scan; `pairs` is the current
    association {track_id: mmsi}."""

    def __init__(self, method: JCost | Chi2Test, *, window: int = 8, gate_m: float = 500.0):
        if not isinstance(method, JCost | Chi2Test):
            raise TypeError(f"method: expected JCost or Chi2Test, got {method!r}")
        if not (isinstance(window, int) and window >= 1):
            raise ValueError(f"window: must be an integer >= 1, got {window!r}")
        self.method = method
        self.window = window
        self.gate_m = _positive("gate_m", gate_m)
        self.pairs: dict[int, int] = {}
        self._hist: dict[tuple[int, int], deque] = {}

    def _release(self, n: int) -> float:
        m = self.method
        return m.release_ratio(n) if isinstance(m, Chi2Test) else m.release

    def update(
        self,
        track_ids: ArrayLike,
        track_states: ArrayLike,
        track_covs: ArrayLike,
        mmsis: ArrayLike,
        ais_states: ArrayLike,
        ais_covs: ArrayLike,
        fresh: ArrayLike | None = None,
    ) -> dict[int, int]:
        """One scan: radar tracks (ids (r,), states (r, 4), covs (r, 4, 4)) and AIS targets
        (mmsi (a,), states (a, 4), covs (a, 4, 4)) at the same time, NED [n, v_n, e, v_e].
        fresh (a,) bool: AIS targets whose latest report is recent enough to be compared
        (default all); a stale target adds no sample and an existing pair with it is kept
        while both exist (the identity does not change because reports are missing).
        Returns the association {track_id: mmsi} after this scan."""
        tid = [int(i) for i in np.asarray(track_ids).ravel()]
        mid = [int(m) for m in np.asarray(mmsis).ravel()]
        xr = as_float_array("track_states", track_states).reshape(len(tid), 4)
        pr = as_float_array("track_covs", track_covs).reshape(len(tid), 4, 4)
        xa = as_float_array("ais_states", ais_states).reshape(len(mid), 4)
        pa = as_float_array("ais_covs", ais_covs).reshape(len(mid), 4, 4)
        ok = np.ones(len(mid), bool) if fresh is None else np.asarray(fresh, bool).ravel()
        if ok.shape != (len(mid),):
            raise ValueError(f"fresh: expected shape ({len(mid)},), got {ok.shape}")
        sampled = set()
        for i, t in enumerate(tid):
            for j, m in enumerate(mid):
                if not ok[j]:
                    continue
                key = (t, m)
                if math.hypot(xr[i, 0] - xa[j, 0], xr[i, 2] - xa[j, 2]) > self.gate_m:
                    self._hist.pop(key, None)
                    continue
                h = self._hist.setdefault(key, deque(maxlen=self.window))
                h.append(self.method.sample(xr[i], pr[i], xa[j], pa[j]))
                sampled.add(key)
        # Forget windows of pairs whose track or target is gone.
        for key in [k for k in self._hist if k[0] not in tid or k[1] not in mid]:
            del self._hist[key]
        # Keep existing pairs while both exist and the cost stays below the release threshold;
        # a fresh target out of the gate (no sample) breaks the pair.
        stale = {m for m, f in zip(mid, ok, strict=True) if not f}
        for t, m in list(self.pairs.items()):
            if t not in tid or m not in mid:
                del self.pairs[t]
            elif m in stale:
                continue
            elif (t, m) not in sampled:
                del self.pairs[t]
            elif self.method.cost(self._hist[(t, m)]) > self._release(len(self._hist[(t, m)])):
                del self.pairs[t]
        # New pairs among the free tracks and targets, one-to-one.
        taken = set(self.pairs.values())
        free_t = [t for t in tid if t not in self.pairs]
        free_m = [m for m in mid if m not in taken]
        if free_t and free_m:
            cost = np.full((len(free_t), len(free_m)), np.inf)
            for a, t in enumerate(free_t):
                for b, m in enumerate(free_m):
                    h = self._hist.get((t, m))
                    if h is not None and (t, m) in sampled and len(h) == self.window:
                        c = self.method.cost(h)
                        if c < 1.0:
                            cost[a, b] = c
            if np.isfinite(cost).any():
                big = np.where(np.isfinite(cost), cost, 1e6)
                rows, cols = linear_sum_assignment(big)
                for a, b in zip(rows, cols, strict=True):
                    if np.isfinite(cost[a, b]):
                        self.pairs[free_t[a]] = free_m[b]
        return dict(self.pairs)

    def cost_of(self, track_id: int, mmsi: int) -> float:
        """The current normalised window cost of a pair (NaN without samples)."""
        h = self._hist.get((int(track_id), int(mmsi)))
        return self.method.cost(h) if h else math.nan


def covariance_intersection(
    x1: ArrayLike, p1: ArrayLike, x2: ArrayLike, p2: ArrayLike, omega: float | None = None
) -> tuple[np.ndarray, np.ndarray, float]:
    """Covariance intersection of two estimates with unknown correlation:
    P⁻¹ = ω P1⁻¹ + (1 − ω) P2⁻¹, x = P (ω P1⁻¹ x1 + (1 − ω) P2⁻¹ x2).

    omega in [0, 1]; None chooses the ω minimising det P (bounded scalar search). Returns
    (x, P, ω). Raises ValueError on shape mismatch or ω outside [0, 1]."""
    a1, a2 = as_float_array("x1", x1, ndim=1), as_float_array("x2", x2, ndim=1)
    c1, c2 = as_float_array("p1", p1, ndim=2), as_float_array("p2", p2, ndim=2)
    n = len(a1)
    if a2.shape != (n,) or c1.shape != (n, n) or c2.shape != (n, n):
        raise ValueError(
            f"x1, p1, x2, p2: shapes do not agree: {a1.shape}, {c1.shape}, {a2.shape}, {c2.shape}"
        )
    i1, i2 = np.linalg.inv(c1), np.linalg.inv(c2)
    if omega is None:

        def logdet(w: float) -> float:
            return -np.linalg.slogdet(w * i1 + (1.0 - w) * i2)[1]

        res = minimize_scalar(logdet, bounds=(0.0, 1.0), method="bounded", options={"xatol": 1e-6})
        w = float(res.x)  # pyright: ignore[reportAttributeAccessIssue]
        for edge in (0.0, 1.0):
            if logdet(edge) < logdet(w):
                w = edge
    else:
        w = float(omega)
        if not 0.0 <= w <= 1.0:
            raise ValueError(f"omega: must be in [0, 1], got {omega!r}")
    info = w * i1 + (1.0 - w) * i2
    p = np.linalg.inv(info)
    p = (p + p.T) / 2.0
    x = p @ (w * i1 @ a1 + (1.0 - w) * i2 @ a2)
    return x, p, w


def same_object(
    position: ArrayLike,
    velocity: ArrayLike,
    t: float,
    plot: ArrayLike,
    t_plot: float,
    t_d: float,
    radius: float,
) -> bool:
    """The paper's §1.2 identity test: the track at `position` (n, e m) with `velocity`
    (v_n, v_e m/s) at time `t` (s) and a plot at `t_plot` in (t, t + t_d] lying within
    `radius` metres of the track's position predicted to `t_plot` are the same object."""
    _positive("radius", radius)
    _positive("t_d", t_d)
    if not t < t_plot <= t + t_d:
        return False
    p = as_float_array("position", position, ndim=1)
    v = as_float_array("velocity", velocity, ndim=1)
    z = as_float_array("plot", plot, ndim=1)
    pred = p + v * (t_plot - t)
    return bool(np.hypot(*(z - pred)) <= radius)
