"""The rotation θ between a camera's ground frame and the VTS frame from matched velocity
vectors (the VTS/camera paper, eq. 3), in closed form instead of the paper's policy-gradient
search.

Vectors are (x, y) of a right-handed plane frame and θ turns camera vectors onto VTS ones
counter-clockwise: v_R ≈ R(θ) v_C with R(θ) = [[cos θ, −sin θ], [sin θ, cos θ]]. The least-
squares rotation of paired vectors (the 2-D Wahba problem) is

    θ = atan2(Σ w_i (v_C × v_R)_i, Σ w_i (v_C · v_R)_i),

and the spread is the weighted RMS of the per-pair angles about it. (For (north, east)
vectors — a left-handed pair — θ is clockwise, i.e. a heading offset.)

`RotationCalibrator` keeps, per camera track, every VTS track whose speed agrees and whose
per-sample angle stays consistent, until exactly one candidate remains (the paper: "the Data
Fusion algorithm continues to calculate the evolution for all the current matches, until a
unique match is finally found"), and estimates θ from the unique matches.
"""

from __future__ import annotations

import math
from collections import defaultdict

import numpy as np
from numpy.typing import ArrayLike

from usvfast._validate import as_float_array

__all__ = ["RotationCalibrator", "rotation_from_velocities"]


def _wrap(a: np.ndarray) -> np.ndarray:
    return np.arctan2(np.sin(a), np.cos(a))


def rotation_from_velocities(
    v_camera: ArrayLike, v_vts: ArrayLike, weights: ArrayLike | None = None
) -> tuple[float, float]:
    """Least-squares θ (rad) with v_vts ≈ R(θ) v_camera for paired vectors (n, 2), and the
    spread (rad): the RMS of the per-pair angles about θ weighted by |v_C||v_R|·w. Raises
    ValueError on shape mismatch, no pair, or all-zero vectors."""
    a = as_float_array("v_camera", v_camera, ndim=2)
    b = as_float_array("v_vts", v_vts, ndim=2)
    if a.shape != b.shape or a.shape[1:] != (2,) or len(a) == 0:
        raise ValueError(f"v_camera, v_vts: expected two (n, 2) arrays, got {a.shape}, {b.shape}")
    w = np.ones(len(a)) if weights is None else as_float_array("weights", weights, ndim=1)
    if w.shape != (len(a),) or np.any(w < 0):
        raise ValueError(f"weights: expected ({len(a)},) values >= 0, got {w.shape}")
    # θ and the spread do not change when a, b or w is scaled: keep the products finite
    a, b, w = (_rescaled(x) for x in (a, b, w))
    cross = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
    dot = a[:, 0] * b[:, 0] + a[:, 1] * b[:, 1]
    sc, sd = float(np.sum(w * cross)), float(np.sum(w * dot))
    if sc == 0.0 and sd == 0.0:
        raise ValueError("v_camera, v_vts: no non-zero pair of vectors")
    theta = math.atan2(sc, sd)
    ww = w * np.hypot(a[:, 0], a[:, 1]) * np.hypot(b[:, 0], b[:, 1])
    per = _wrap(np.arctan2(cross, dot) - theta)
    spread = float(np.sqrt(np.sum(ww * per**2) / np.sum(ww))) if ww.sum() > 0 else math.nan
    return theta, spread


def _rescaled(x: np.ndarray) -> np.ndarray:
    """`x` divided by its largest |value| when that is beyond 1e±100 (a new array), else x."""
    top = float(np.abs(x).max())
    return x / top if top > 1e100 or 0.0 < top < 1e-100 else x


class RotationCalibrator:
    """Camera ↔ VTS track matching by velocity, and θ from the matches (module docstring).

    Each `add` is one time step: camera tracks (ids, velocities (n, 2)) and VTS tracks (ids,
    velocities (m, 2)) in their own frames. Steps with both moving faster than `min_speed`
    (m/s) are samples of the pair (camera i, VTS j) when their speeds agree within
    `speed_tol` (m/s), else mismatches (a young track's velocity is still converging). The
    pair is a candidate while its samples outnumber its mismatches and the angles from camera
    to VTS vector stay within `angle_tol_deg` of their circular mean; once some camera tracks
    have a unique candidate (with `min_samples` samples), the others' candidates must also
    agree with the θ of those within `angle_tol_deg`."""

    def __init__(
        self,
        *,
        speed_tol: float = 1.0,
        angle_tol_deg: float = 10.0,
        min_speed: float = 1.0,
        min_samples: int = 3,
    ) -> None:
        for name, v in (
            ("speed_tol", speed_tol),
            ("angle_tol_deg", angle_tol_deg),
            ("min_speed", min_speed),
        ):
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"{name}: must be finite and > 0, got {v!r}")
        if not (isinstance(min_samples, int) and min_samples >= 1):
            raise ValueError(f"min_samples: must be an integer >= 1, got {min_samples!r}")
        self.speed_tol, self.min_speed, self.min_samples = speed_tol, min_speed, min_samples
        self.angle_tol = math.radians(angle_tol_deg)
        self._samples: dict[tuple[int, int], list[tuple[np.ndarray, np.ndarray]]] = defaultdict(
            list
        )
        self._mismatch: dict[tuple[int, int], int] = defaultdict(int)

    def add(
        self, camera_ids: ArrayLike, v_camera: ArrayLike, vts_ids: ArrayLike, v_vts: ArrayLike
    ) -> None:
        """One time step of both trackers' velocities (see the class)."""
        ci = [int(i) for i in np.asarray(camera_ids).ravel()]
        vi = [int(j) for j in np.asarray(vts_ids).ravel()]
        a = as_float_array("v_camera", v_camera).reshape(len(ci), 2)
        b = as_float_array("v_vts", v_vts).reshape(len(vi), 2)
        sa, sb = np.hypot(a[:, 0], a[:, 1]), np.hypot(b[:, 0], b[:, 1])
        for p, i in enumerate(ci):
            if sa[p] <= self.min_speed:
                continue
            for q, j in enumerate(vi):
                if sb[q] <= self.min_speed:
                    continue
                if abs(sa[p] - sb[q]) > self.speed_tol:
                    self._mismatch[(i, j)] += 1
                else:
                    self._samples[(i, j)].append((a[p], b[q]))

    def _pair_angles(self, key: tuple[int, int]) -> np.ndarray:
        s = self._samples[key]
        a = np.array([x for x, _ in s])
        b = np.array([y for _, y in s])
        return np.arctan2(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0], np.sum(a * b, axis=1))

    def _consistent(self, key: tuple[int, int], theta: float | None) -> bool:
        if len(self._samples[key]) <= self._mismatch.get(key, 0):
            return False
        ang = self._pair_angles(key)
        mean = math.atan2(np.sin(ang).mean(), np.cos(ang).mean())
        if np.max(np.abs(_wrap(ang - mean))) > self.angle_tol:
            return False
        return theta is None or bool(abs(_wrap(np.array(mean - theta))) <= self.angle_tol)

    def candidates(self) -> dict[int, list[int]]:
        """{camera id: VTS ids still possible}, after the θ of the unique matches is applied."""
        cands: dict[int, list[int]] = defaultdict(list)
        for key in self._samples:
            if self._consistent(key, None):
                cands[key[0]].append(key[1])
        unique = {
            i: js[0]
            for i, js in cands.items()
            if len(js) == 1 and len(self._samples[(i, js[0])]) >= self.min_samples
        }
        if unique:
            theta = self._estimate(unique)[0]
            cands = defaultdict(list)
            for key in self._samples:
                if self._consistent(key, theta):
                    cands[key[0]].append(key[1])
        return {i: sorted(js) for i, js in cands.items()}

    def matches(self) -> dict[int, int]:
        """{camera id: VTS id} for camera tracks with exactly one candidate left."""
        return {
            i: js[0]
            for i, js in self.candidates().items()
            if len(js) == 1 and len(self._samples[(i, js[0])]) >= self.min_samples
        }

    def _estimate(self, pairs: dict[int, int]) -> tuple[float, float, int]:
        a = np.array([x for i, j in pairs.items() for x, _ in self._samples[(i, j)]])
        b = np.array([y for i, j in pairs.items() for _, y in self._samples[(i, j)]])
        theta, spread = rotation_from_velocities(a, b)
        return theta, spread, len(a)

    def estimate(self) -> tuple[float, float, int]:
        """(θ rad, spread rad, number of samples) from the unique matches; NaNs and 0 when
        there is none yet."""
        m = self.matches()
        if not m:
            return math.nan, math.nan, 0
        return self._estimate(m)
