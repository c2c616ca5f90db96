"""The camera chain of the pipeline (thesis Code 5.5 generalised): detector -> image filters
(confidence, own-vessel polygon, horizon from the attitude) -> georeferencing onto the water
with per-detection covariance (lens distortion undone on the contact points) -> range gate.

The detector is any callable `images -> [Detections | (boxes, scores[, classes])]` (see
`usvfast.camera.yolo.CameraPipeline`); `load_detector` builds it from the [detector] table:
"torch" (usvfast.camera.yolo.YoloDetector), "onnx" (OpenCV DNN) or "none" (no camera
detections).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from usvfast.camera.backends import load_detector as _load_backend
from usvfast.camera.chain import CameraPipeline
from usvfast.camera.detect import Detections, as_detections
from usvfast.camera.georef import (
    OK,
    FovCamera,
    box_contact_points,
    georeference,
    horizon_line,
    mount_rotation,
)
from usvfast.camera.vessels import (
    MovingBoats,
    fuse_boxes,
    hull_centre,
    hull_covariance,
    separate,
)
from usvfast.frames import Mount
from usvfast.pipeline.pose import VesselPose
from usvfast.pipeline.timing import StageTimer

__all__ = ["CameraChain", "CameraResult", "load_camera", "load_detector"]


def load_camera(settings: dict[str, Any]) -> Any:
    """The camera model of the [camera] table: a calibration file (ROS camera_info YAML or
    our JSON, `usvfast.camera.CameraModel`) or the thesis's FOV model (image_size, fov_deg)."""
    from usvfast.camera.calibration import CameraModel

    if settings.get("calibration") is not None:
        try:
            return CameraModel.load(settings["calibration"])
        except (OSError, ValueError, TypeError) as exc:
            raise ValueError(
                f"camera.calibration: cannot load {settings['calibration']}: {exc}"
            ) from exc
    if settings.get("image_size") is None or settings.get("fov_deg") is None:
        raise ValueError("camera.calibration: missing (or give camera.image_size and fov_deg)")
    w, h = settings["image_size"]
    return FovCamera((int(w), int(h)), tuple(settings["fov_deg"]))


def load_detector(settings: dict[str, Any], base: Any = None) -> Any:
    """The detector callable of the [detector] table, or None for backend "none". Relative
    weights are looked up from `base` (the config's folder), then among the bundled models
    (usvfast.camera.backends.load_detector)."""
    backend = settings.get("backend", "none")
    if backend == "none":
        return None
    options: dict[str, Any] = dict(
        conf_threshold=settings["conf_threshold"], iou_threshold=settings["iou_threshold"]
    )
    if settings.get("input_size") is not None:
        options["input_size"] = tuple(int(v) for v in settings["input_size"])
    if settings.get("classes") is not None:
        options["classes"] = [int(c) for c in settings["classes"]]
    if backend == "onnx":
        options["runtime"] = settings.get("runtime", "auto")
    try:
        return _load_backend(backend, settings["weights"], base=base, **options)
    except FileNotFoundError as exc:
        raise ValueError(f"detector.weights: {exc}") from exc


@dataclass(frozen=True)
class CameraResult:
    """Georeferenced detections of one frame: positions (k, 2) NED m, covariances (k, 2, 2)
    m², scores (k,), boxes (k, 4) xyxy px; `n_boxes` detector boxes before the filters,
    `rejected` {reason: count}; `vessel` (k,) bool: the moving boats (camera.moving_classes),
    None when there are none."""

    positions: np.ndarray
    covariances: np.ndarray
    scores: np.ndarray
    boxes: np.ndarray
    n_boxes: int
    rejected: dict[str, int]
    vessel: np.ndarray | None = None


class CameraChain:
    """One camera stream through the chain; `process(image, pose)` -> CameraResult.

    settings: the config's [camera] table; detector: the callable (see module doc); mount:
    the stream's mount (lever arm body FRD m, ypr as `usvfast.camera.mount_rotation`).
    """

    def __init__(
        self,
        settings: dict[str, Any],
        detector: Any,
        mount: Mount | None,
        timer: StageTimer,
    ) -> None:
        self.settings = settings
        self.camera = load_camera(settings)
        self.detector = detector
        mount = mount or Mount()
        lever = np.asarray(mount.lever_arm, dtype=np.float64)
        ypr = [math.degrees(mount.yaw), math.degrees(mount.pitch), math.degrees(mount.roll)]
        self.rotation = mount_rotation(ypr)
        self.position = lever
        water = settings.get("waterline_height")
        if water is None:
            raise ValueError(
                "camera.waterline_height: missing; give the vessel reference point's height "
                "above the water"
            )
        self.height = float(water) - float(lever[2])
        if not self.height > 0:
            raise ValueError(
                f"camera.waterline_height: the camera is {self.height} m above the water "
                "(waterline_height - lever_arm z must be > 0)"
            )
        fixed = settings.get("horizon_line") if settings.get("horizon") == "line" else None
        self.filters = CameraPipeline(
            detector=detector or (lambda images: [Detections.empty() for _ in images]),
            camera=self.camera,
            height=self.height,
            min_confidence=float(settings.get("min_confidence", 0.0)),
            own_vessel_polygon=None
            if settings.get("own_vessel_polygon") is None
            else np.asarray(settings["own_vessel_polygon"], dtype=np.float64),
            horizon_line=None if fixed is None else (float(fixed[0]), float(fixed[1])),
        )
        self.timer = timer
        self.depth_table = _depth_table(settings)
        moving = settings.get("moving_classes")
        self.moving_classes = None if moving is None else [int(c) for c in moving]
        low = settings.get("low_boat_classes")
        self.low_boat_classes = [] if low is None else [int(c) for c in low]
        self.boats = MovingBoats(
            history_s=float(settings.get("vessel_history_s", 2.0)),
            min_speed=float(settings.get("vessel_min_speed", 1.0)),
            min_frames=int(settings.get("vessel_min_frames", 5)),
        )

    def _horizon(self, pose: VesselPose) -> tuple[float, float] | None:
        if self.settings.get("horizon") != "attitude" or not hasattr(self.camera, "project"):
            return self.filters.horizon_line
        try:
            return horizon_line(
                self.camera,
                mount_rotation=self.rotation,
                roll=pose.roll,
                pitch=pose.pitch,
                margin_deg=float(self.settings.get("horizon_margin_deg", 0.0)),
            )
        except ValueError:
            return None  # horizon not in front of the camera: georeferencing still gates rays

    def process(self, image: np.ndarray, pose: VesselPose) -> CameraResult:
        """Detect, filter and georeference one frame taken at `pose`."""
        with self.timer("camera.detector"):
            raw = self.detect(image)
        return self.finish(raw, pose)

    def detect(self, image: np.ndarray) -> Any:
        """The detector's raw result on one frame (no state: safe on a worker thread while
        the caller runs other chains; `finish` then completes the frame)."""
        return self.detector([image])[0] if self.detector is not None else Detections.empty()

    def finish(self, raw: Any, pose: VesselPose) -> CameraResult:
        """Filter and georeference the detector's result `raw` of a frame taken at `pose`."""
        from usvfast.camera.georef import REASONS

        tm = self.timer
        det = as_detections(raw)
        with tm("camera.filters"):
            self.filters.horizon_line = self._horizon(pose)
            reason = self.filters.filter(det)
        ok = reason == OK
        boat = np.zeros(len(det.boxes), bool)
        if self.moving_classes is not None:
            boat = np.isin(det.classes, self.moving_classes)
            if self.low_boat_classes and boat.any():
                with tm("camera.vessels"):
                    boat &= ~self._low_boats(det, ok, pose)
            reason[boat] = np.where(ok[boat], -1, reason[boat])
            ok &= ~boat
        positions = np.zeros((0, 2))
        covs = np.zeros((0, 2, 2))
        if ok.any():
            boxes = det.boxes[ok]
            with tm("camera.georeference"):
                g = self._georeference(boxes, pose)
            reason[ok] = g.reason
            good = g.reason == OK
            positions, covs = g.positions[good], g.covariances[good]
            depth = float(self.settings.get("object_depth_factor", 0.0))
            fixed, sigma = self._class_depths(det.classes[ok][good])
            if (depth > 0 or np.isfinite(fixed).any()) and good.any():
                with tm("camera.georeference"):
                    positions = self._to_centre(boxes[good], positions, pose, depth, fixed)
                covs = covs + (sigma**2)[:, None, None] * np.eye(2)
            s = self.settings
            along, across = s.get("centre_along_std", 0.0), s.get("centre_across_std", 0.0)
            if (along > 0 or across > 0) and good.any():
                covs = covs + hull_covariance(positions, self._camera_ne(pose), along, across)
        keep = reason == OK
        rejected: dict[str, int] = {}
        for code in np.unique(reason[~keep & (reason >= 0)]):
            rejected[REASONS[int(code)]] = int(np.sum(reason == code))
        scores, boxes = det.scores[keep], det.boxes[keep]
        vessel = None
        if self.moving_classes is not None:
            with tm("camera.vessels"):
                vp, vc, vs, vb, still = self._vessels(
                    det.boxes[reason == -1], det.scores[reason == -1], pose
                )
            positions, covs = np.vstack([positions, vp]), np.concatenate([covs, vc])
            scores, boxes = np.concatenate([scores, vs]), np.vstack([boxes.reshape(-1, 4), vb])
            if still:
                rejected["not_moving"] = still
            vessel = np.r_[np.zeros(len(positions) - len(vp), bool), np.ones(len(vp), bool)]
        return CameraResult(positions, covs, scores, boxes, len(det.boxes), rejected, vessel)

    def _low_boats(self, det: Any, ok: np.ndarray, pose: VesselPose) -> np.ndarray:
        """Mask (k,) of the boxes of camera.low_boat_classes that passed the filters and span
        less than camera.vessel_min_height m above the water: too low for a hull and cabin,
        they are floating objects that the network called boats (the float path takes them,
        as it does without camera.moving_classes)."""
        cand = ok & np.isin(det.classes, self.low_boat_classes)
        low = np.zeros(len(det.boxes), bool)
        if not cand.any():
            return low
        boxes = det.boxes[cand]
        g = self._georeference(boxes, pose)
        height = np.full(len(boxes), np.nan)
        good = g.reason == OK
        if good.any():
            height[good] = self._box_height(boxes[good], g.positions[good], pose)
        min_height = float(self.settings.get("vessel_min_height", 1.2))
        low[np.flatnonzero(cand)] = good & (height < min_height)
        return low

    def _vessels(
        self, boxes: np.ndarray, scores: np.ndarray, pose: VesselPose
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, int]:
        """The boat-class boxes of a frame (camera.moving_classes; usvfast.camera.vessels):
        boxes within camera.vessel_edge_margin_px of the image's side edges dropped (a hull
        cut by the edge is boxed off its centre), overlapping boxes fused, fused boxes that
        span less than camera.vessel_min_height m above the water dropped, the fused box's
        waterline point georeferenced and kept only while the boat moves (and is the best
        of the moving boats within camera.vessel_separation m); then moved to the
        hull's centre with the hull's covariance. Returns positions, covariances, scores,
        boxes of the moving boats and the number of boats that did not move."""
        s = self.settings
        width = float(self.camera.image_size[0])
        margin = float(s.get("vessel_edge_margin_px", 16.0))
        inside = (boxes[:, 0] > margin) & (boxes[:, 2] < width - margin)
        fused, best = fuse_boxes(boxes[inside], scores[inside])
        empty = (np.zeros((0, 2)), np.zeros((0, 2, 2)), np.zeros(0), np.zeros((0, 4)))
        g = self._georeference(fused, pose) if len(fused) else None
        good = np.zeros(0, bool) if g is None else g.reason == OK
        if g is not None and good.any():
            good &= self._box_height(fused, g.positions, pose) >= float(
                s.get("vessel_min_height", 1.2)
            )
        contact = np.zeros((0, 2)) if g is None else g.positions[good]
        vel, moving = self.boats.update(pose.time, contact)
        if moving.any():
            sep = separate(
                contact[moving], best[good][moving], float(s.get("vessel_separation", 9.0))
            )
            moving[np.flatnonzero(moving)[~sep]] = False
        if g is None or not moving.any():
            return (*empty, int(good.sum()))
        cam = self._camera_ne(pose)
        centre, _ = hull_centre(
            contact[moving],
            cam,
            vel[moving],
            float(s.get("vessel_length", 6.0)),
            float(s.get("vessel_beam", 2.2)),
        )
        cov = g.covariances[good][moving] + hull_covariance(
            contact[moving],
            cam,
            float(s.get("vessel_along_std", 1.0)),
            float(s.get("vessel_across_std", 0.6)),
        )
        kept = fused[good][moving], best[good][moving]
        return centre, cov, kept[1], kept[0], int((~moving).sum())

    def _box_height(self, boxes: np.ndarray, contact: np.ndarray, pose: VesselPose) -> np.ndarray:
        """Height (k,) m above the water that each box spans at the horizontal distance of its
        georeferenced bottom point `contact` (k, 2) NED m: the distance times the difference of
        the normalised image coordinates of its top and bottom centres (lens distortion
        undone; small-angle, NaN where the bottom did not georeference)."""
        u = (boxes[:, 0] + boxes[:, 2]) / 2.0
        top, _ = self.camera.normalized(np.column_stack([u, boxes[:, 1]]))
        bottom, _ = self.camera.normalized(np.column_stack([u, boxes[:, 3]]))
        dist = np.hypot(*(np.asarray(contact, float) - self._camera_ne(pose)[None]).T)
        return dist * (bottom[:, 1] - top[:, 1])

    def _camera_ne(self, pose: VesselPose) -> np.ndarray:
        """The camera's (north, east) m at `pose` (its lever arm turned by the heading)."""
        lx, ly = float(self.position[0]), float(self.position[1])
        ch, sh = math.cos(pose.heading), math.sin(pose.heading)
        return np.array([pose.north + ch * lx - sh * ly, pose.east + sh * lx + ch * ly])

    def coverage(self) -> tuple[float, float, float]:
        """(range m, horizontal field of view deg, axis yaw deg clockwise from the heading):
        max_range (40 m when unset) and the angle between the rays through the left and
        right image edges at the principal point's row (lens distortion undone)."""
        w, h = self.camera.image_size
        cy = float(h) / 2.0
        matrix = getattr(self.camera, "camera_matrix", None)
        if matrix is not None:
            cy = float(np.asarray(matrix)[1, 2])
        norm, _ = self.camera.normalized(np.array([[-0.5, cy], [float(w) - 0.5, cy]]))
        fov = math.degrees(math.atan(abs(norm[0, 0])) + math.atan(abs(norm[1, 0])))
        yaw = math.degrees(math.atan2(self.rotation[1, 2], self.rotation[0, 2]))
        rng = self.settings.get("max_range")
        return (float(rng) if rng is not None else 40.0, fov, yaw)

    def _georeference(self, boxes: np.ndarray, pose: VesselPose, which: str = "contact") -> Any:
        """Georeference the boxes' water-contact points (`which` "contact": bottom centre;
        "left" / "right": bottom corners). Box coordinates count pixel edges (pixel i spans
        [i, i + 1]) while the camera models put pixel centres at integers: the points are
        moved by -box_pixel_offset in u and v."""
        s = self.settings
        offset = float(s.get("box_pixel_offset", 0.5))
        if which == "contact":
            px = box_contact_points(boxes)
        else:
            px = boxes[:, [0, 3] if which == "left" else [2, 3]].astype(np.float64)
        px = px - offset
        sigma = s.get("pixel_sigma_uv")
        return georeference(
            px,
            self.camera,
            height=self.height,
            mount_rotation=self.rotation,
            mount_position=self.position,
            roll=pose.roll,
            pitch=pose.pitch,
            heading=pose.heading,
            vessel_ne=(pose.north, pose.east),
            pixel_sigma=tuple(sigma) if sigma is not None else s.get("pixel_sigma", 0.0),
            attitude_sigma=math.radians(s.get("attitude_sigma_deg", 0.0)),
            height_sigma=s.get("height_sigma", 0.0),
            heading_sigma=math.radians(s.get("heading_sigma_deg", 0.0)),
            min_depression_deg=s.get("min_depression_deg", 0.0),
            max_range=s.get("max_range"),
        )

    def _class_depths(self, classes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Per box: the fixed centre depth of its class (m beyond the near waterline; NaN:
        none, use object_depth_factor) and the standard deviation (m) of that centre, from
        camera.depth_classes / class_depth_m / class_depth_std_m."""
        fixed = np.full(len(classes), np.nan)
        sigma = np.zeros(len(classes))
        for c, d, sd in self.depth_table:
            hit = classes == c
            fixed[hit], sigma[hit] = d, sd
        return fixed, sigma

    def _to_centre(
        self,
        boxes: np.ndarray,
        contact: np.ndarray,
        pose: VesselPose,
        factor: float,
        fixed: np.ndarray | None = None,
    ) -> np.ndarray:
        """The box's bottom edge images the object's near waterline; its centre lies farther
        along the line of sight by half its depth. With an unknown yaw the depth is on average
        the width seen across the line of sight (the distance between the georeferenced
        bottom corners), so the point moves `factor` x that width away from the camera —
        or, where `fixed` (per box, m) is finite, by that distance (a class whose depth is
        known, e.g. half a vessel's beam: a long hull's seen width is its length)."""
        left = self._georeference(boxes, pose, "left").positions
        right = self._georeference(boxes, pose, "right").positions
        width = np.linalg.norm(right - left, axis=1)
        cam = self._camera_ne(pose)
        los = contact - cam
        rng = np.linalg.norm(los, axis=1, keepdims=True)
        shift = np.where(np.isfinite(width), factor * width, 0.0)
        if fixed is not None:
            shift = np.where(np.isfinite(fixed), fixed, shift)
        shift = shift[:, None]
        return contact + shift * los / np.maximum(rng, 1e-9)


def _depth_table(s: dict[str, Any]) -> list[tuple[int, float, float]]:
    """(class id, centre depth m, its standard deviation m) from camera.depth_classes,
    class_depth_m and class_depth_std_m (default 0); ValueError naming the keys when they
    do not line up."""
    ids = s.get("depth_classes") or ()
    depth = s.get("class_depth_m") or ()
    std = s.get("class_depth_std_m") or (0.0,) * len(ids)
    if not (len(ids) == len(depth) == len(std)) or any(int(c) != c for c in ids):
        raise ValueError(
            "camera.depth_classes, class_depth_m, class_depth_std_m: expected lists of the same "
            f"length (class ids, m, m), got {ids!r}, {depth!r}, {std!r}"
        )
    if any(d < 0 for d in depth) or any(v < 0 for v in std):
        raise ValueError("camera.class_depth_m, class_depth_std_m: must be >= 0")
    return [(int(c), float(d), float(v)) for c, d, v in zip(ids, depth, std, strict=True)]
