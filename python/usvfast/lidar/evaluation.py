"""Score the LiDAR detector on simulated scenes against the simulator's ground truth.

For each buffered cycle, a floating object counts as *visible* when the simulator says it
returned points inside the detector's range and water slice during the cycle, and as
*detectable* when those returns are at least `min_cluster_points` (a cluster needs that
many). It is *detected* when a kept cluster's points come mostly from it. A kept cluster
whose points come mostly from a wall, a boat or surface clutter is a *false* detection.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from usvfast._validate import integer, real
from usvfast.lidar.pipeline import LidarConfig, LidarDetector
from usvfast.lidar.simulator import FLOAT, Scene, VLP16Simulator


@dataclass
class CycleScore:
    """One cycle: ids of visible / detectable / detected floats, and the false detections
    as (kind, n_points, (north, east))."""

    stamp: float
    visible: set[int]
    detectable: set[int]
    detected: set[int]
    false: list[tuple[str, int, tuple[float, float]]]


@dataclass
class SceneScore:
    """All cycles of a run, with totals."""

    cycles: list[CycleScore] = field(default_factory=list)

    @property
    def detectable(self) -> int:
        """Sum over cycles of the detectable floats."""
        return sum(len(c.detectable) for c in self.cycles)

    @property
    def visible(self) -> int:
        """Sum over cycles of the visible floats."""
        return sum(len(c.visible) for c in self.cycles)

    @property
    def detected(self) -> int:
        """Sum over cycles of the detectable floats that were detected."""
        return sum(len(c.detected & c.detectable) for c in self.cycles)

    @property
    def detected_visible(self) -> int:
        """Sum over cycles of the visible floats that were detected."""
        return sum(len(c.detected & c.visible) for c in self.cycles)

    @property
    def false(self) -> int:
        """Number of detections not coming from a floating object."""
        return sum(len(c.false) for c in self.cycles)

    @property
    def worst_cycle_rate(self) -> float:
        """Lowest per-cycle fraction of detectable floats detected (1.0 if none)."""
        rates = [
            len(c.detected & c.detectable) / len(c.detectable) for c in self.cycles if c.detectable
        ]
        return min(rates, default=1.0)

    def summary(self) -> str:
        """One line of figures."""
        return (
            f"{len(self.cycles)} cycles: detected {self.detected}/{self.detectable} detectable "
            f"float-cycles ({100 * self.detected / max(self.detectable, 1):.1f} %, worst cycle "
            f"{100 * self.worst_cycle_rate:.0f} %), {self.detected_visible}/{self.visible} of all "
            f"hit float-cycles, {self.false} false detections"
        )


def evaluate_scene(
    scene: Scene,
    poses: np.ndarray,
    stamps: np.ndarray,
    *,
    config: LidarConfig | None = None,
    seed: int = 0,
    mount_height: float | None = None,
) -> SceneScore:
    """Simulate a VLP-16 along `poses` (t, 3) (north, east, heading) at `stamps` (t,), run a
    `LidarDetector` with `config` and score every cycle against the ground truth."""
    cfg = config or LidarConfig()
    height = cfg.mount_height if mount_height is None else mount_height
    sim = VLP16Simulator(
        scene, mount_height=height, lever_arm=cfg.lever_arm, mount_yaw=cfg.mount_yaw, seed=seed
    )
    detector = LidarDetector(cfg)
    kinds = scene.kinds()
    truth: dict[int, np.ndarray] = {}
    counts: dict[int, int] = {}
    score = SceneScore()
    for pose, stamp in zip(np.asarray(poses, float), np.asarray(stamps, float), strict=True):
        sf = sim.scan(pose, stamp)
        truth[sf.frame.index] = sf.labels
        p = sf.frame.points
        h = p["z"].astype(np.float64) + height
        seen = (
            (p["x"].astype(np.float64) ** 2 + p["y"].astype(np.float64) ** 2 <= cfg.radius**2)
            & (h >= cfg.slice_min)
            & (h <= cfg.slice_max)
            & (sf.labels >= 0)
        )
        for k, c in zip(*np.unique(sf.labels[seen], return_counts=True), strict=True):
            if kinds[k] == FLOAT:
                counts[int(k)] = counts.get(int(k), 0) + int(c)
        result = detector.process(sf.frame, pose)
        cycle = result.cycle
        if cycle is None:
            continue
        source = np.array(
            [truth[f][j] for f, j in zip(cycle.frame_index, cycle.point_index, strict=True)],
            dtype=np.int64,
        )
        detected: set[int] = set()
        false = []
        for k in np.unique(cycle.labels[cycle.labels >= 0]):
            members = source[cycle.labels == k]
            ids, n = np.unique(members, return_counts=True)
            owner = int(ids[np.argmax(n)])
            if owner >= 0 and kinds[owner] == FLOAT:
                detected.add(owner)
            else:
                centre = cycle.points[cycle.labels == k].mean(axis=0)
                kind = "clutter" if owner < 0 else str(kinds[owner])
                false.append((kind, int(members.size), (float(centre[0]), float(centre[1]))))
        score.cycles.append(
            CycleScore(
                cycle.stamp,
                set(counts),
                {k for k, c in counts.items() if c >= cfg.min_cluster_points},
                detected,
                false,
            )
        )
        truth.clear()
        counts = {}
    return score


def straight_run(
    frames: int, *, speed: float = 1.0, rate: float = 10.0, yaw_rate: float = 0.0, t0: float = 0.0
) -> tuple[np.ndarray, np.ndarray]:
    """Poses (frames, 3) and stamps of a vessel leaving the origin heading north at `speed`
    m/s, turning at `yaw_rate` rad/s, one frame every 1/`rate` s (unicycle model)."""
    frames = integer("frames", frames, low=0, high=10**8)
    speed, yaw_rate, t0 = real("speed", speed), real("yaw_rate", yaw_rate), real("t0", t0)
    rate = real("rate", rate, positive=True)
    stamps = t0 + np.arange(frames) / rate
    heading = yaw_rate * (stamps - t0)
    dt = 1.0 / rate
    north = np.concatenate([[0.0], np.cumsum(speed * dt * np.cos(heading[:-1]))])
    east = np.concatenate([[0.0], np.cumsum(speed * dt * np.sin(heading[:-1]))])
    return np.column_stack([north, east, heading]), stamps
