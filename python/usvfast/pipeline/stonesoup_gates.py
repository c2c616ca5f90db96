"""Stone Soup components for the native tracker's `initiate_in_gates=False` (no duplicate
tracks on one target), so that Stone Soup's own `MultiTargetMixtureTracker` /
`MultiTargetTracker` runs the same configuration.

The native rule (usvfast.tracking module docstring): the initiator is not offered any
detection inside a confirmed track's gate, and a tentative track about to be confirmed is
dropped when its position lies inside the gate of a confirmed track (or of one confirmed
before it in the same scan). In Stone Soup's tracker loop (`MultiTargetMixtureTracker.__next__`)
the data associator hypothesises every confirmed track, the tracks are updated, the deleter
runs, and then `initiator.initiate(unassociated_detections, time)` is called. So:

- `GateRecorder` wraps the association's hypothesiser and remembers every detection it put
  in some track's gate (its non-missed hypotheses) during the scan;
- `InGateInitiator` wraps the real `MultiMeasurementInitiator`: it removes the recorded
  detections from those it is given, lets the wrapped initiator associate, update and
  confirm its tentative tracks, and then drops each newly confirmed track whose position
  H x (as a pseudo-detection of the sensor of its last update, with that sensor's R) lies in
  the gate of a confirmed track of the tracker (updated and after deletion, as the native
  core holds them) or of a candidate accepted before it. Candidates are taken in the order
  the native core keeps its tentative tracks: by the scan that started them, then by the
  row of their first detection in that scan (`Detection.metadata["row"]`).

The duplicate gate is squared Mahalanobis distance yᵀ S⁻¹ y <= `gate_threshold`, with
S = H P Hᵀ + R from the updater's `predict_measurement`; the native core uses the
association gate widened to at least χ²_m(0.9999) (`duplicate_gate`).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from scipy.stats import chi2
from stonesoup.base import Property
from stonesoup.hypothesiser import Hypothesiser
from stonesoup.initiator import Initiator
from stonesoup.initiator.simple import MultiMeasurementInitiator
from stonesoup.measures import SquaredMahalanobis
from stonesoup.types.detection import Detection
from stonesoup.types.update import Update

__all__ = ["GateRecorder", "InGateInitiator", "StartingInitiator", "duplicate_gate"]


def duplicate_gate(association_gate: float, ndim_meas: int = 2) -> float:
    """The native core's duplicate gate (squared Mahalanobis): the association gate
    (JPDA: χ²_m(P_G); GNN: missed_distance²), at least χ²_m(0.9999), χ²_m(0.9999) when the
    association gate is infinite."""
    wide = float(chi2.ppf(0.9999, ndim_meas))
    g = float(association_gate)
    return max(g, wide) if g < float("inf") else wide


class GateRecorder(Hypothesiser):
    """A hypothesiser that delegates to `hypothesiser` and records, in `gated`, the
    detections of its non-missed hypotheses (those inside some track's gate) until
    `take()` hands them out and forgets them."""

    hypothesiser: Any = Property(doc="The association's Hypothesiser.")

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        if not isinstance(self.hypothesiser, Hypothesiser):
            raise TypeError(f"hypothesiser: expected a Hypothesiser, got {self.hypothesiser!r}")
        self.gated: set[Detection] = set()

    def hypothesise(self, track: Any, detections: Any, timestamp: Any, **kwargs: Any) -> Any:
        """The wrapped hypothesiser's hypotheses; their detections are recorded."""
        hyps = self.hypothesiser.hypothesise(track, detections, timestamp, **kwargs)
        self.gated.update(h.measurement for h in hyps if h)
        return hyps

    def take(self) -> set[Detection]:
        """The detections gated since the last call."""
        out, self.gated = self.gated, set()
        return out


class StartingInitiator(MultiMeasurementInitiator):
    """Stone Soup's `MultiMeasurementInitiator` whose new tentative tracks start only from
    detections without `metadata["starts"] = False` (the native `Sensor.starts_tracks`): the
    others are still associated with, and update, the tentative tracks it holds. The tracks it
    would start from them are dropped as soon as they are made (a new track changes nothing
    else in the scan)."""

    def initiate(self, detections: Any, timestamp: Any, **kwargs: Any) -> set[Any]:
        """The tracks confirmed at `timestamp`; see the class docstring."""
        held = set(self.holding_tracks)
        sure = super().initiate(detections, timestamp, **kwargs)
        self.holding_tracks -= {
            tr for tr in self.holding_tracks - held if not _first_detection_starts(tr)
        }
        return sure


def _first_detection_starts(track: Any) -> bool:
    meas = getattr(getattr(track.states[0], "hypothesis", None), "measurement", None)
    return meas is None or meas.metadata.get("starts", True) is not False


class InGateInitiator(Initiator):
    """Stone Soup's `MultiMeasurementInitiator` (`initiator`) with the native tracker's
    duplicate suppression (see the module docstring). Set `confirmed` to a callable giving the
    tracker's confirmed tracks (e.g. `lambda: tracker.tracks`) before the first scan.

    recorder: the `GateRecorder` of the tracker's association (None: no detection withheld,
    as the native core under GNN). sensor_models: the measurement model of each sensor
    (`Detection.metadata["sensor"]` indexes it) for the pseudo-detection of a candidate;
    None, or a detection without that key: the candidate's last detection's own model.
    Both are required (give None explicitly).
    """

    initiator: Any = Property(doc="The wrapped MultiMeasurementInitiator.")
    updater: Any = Property(doc="An Updater: S = H P Hᵀ + R from its predict_measurement.")
    gate_threshold: Any = Property(doc="Duplicate gate (float), squared Mahalanobis distance.")
    recorder: Any = Property(doc="GateRecorder of the association, or None.")
    sensor_models: Any = Property(doc="Measurement model per sensor index, or None.")

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        if not isinstance(self.initiator, MultiMeasurementInitiator):
            raise TypeError(
                f"initiator: expected MultiMeasurementInitiator, got {self.initiator!r}"
            )
        self.confirmed: Callable[[], Any] = set
        self._measure = SquaredMahalanobis(state_covar_inv_cache_size=0)
        self._born: dict[Any, tuple[int, int]] = {}
        self._scans = 0
        #: detections withheld from the initiator (inside a gate) and candidates dropped
        self.withheld = 0
        self.dropped = 0

    @property
    def holding_tracks(self) -> set[Any]:
        """The wrapped initiator's tentative tracks."""
        return self.initiator.holding_tracks

    def _model(self, det: Detection) -> Any:
        s = det.metadata.get("sensor")
        if self.sensor_models is not None and s is not None:
            return self.sensor_models[int(s)]
        return det.measurement_model

    def _pseudo_detection(self, track: Any) -> Detection:
        st: Any = track.state
        hyp = getattr(st, "hypothesis", None) if isinstance(st, Update) else None
        meas = getattr(hyp, "measurement", None)
        if meas is None or not hasattr(meas, "metadata"):
            model = self.sensor_models[0] if self.sensor_models else None
        else:
            model = self._model(meas)
        if model is None:
            raise ValueError("sensor_models: no measurement model for a confirmed candidate")
        z = model.function(st, noise=False)
        return Detection(z, timestamp=track.timestamp, measurement_model=model)

    def _in_gate(self, track: Any, det: Detection) -> bool:
        pred = self.updater.predict_measurement(track.state, det.measurement_model)
        return float(self._measure(pred, det)) <= self.gate_threshold

    def initiate(self, detections: Any, timestamp: Any, **kwargs: Any) -> set[Any]:
        """Tracks confirmed at `timestamp` from `detections` (see the class docstring)."""
        withheld = self.recorder.take() if self.recorder is not None else set()
        free = set(detections) - withheld
        self.withheld += len(detections) - len(free)
        sure = self.initiator.initiate(free, timestamp, **kwargs)
        self._scans += 1
        for tr in self.initiator.holding_tracks:
            if tr not in self._born:
                first = tr.states[0]
                meas = getattr(getattr(first, "hypothesis", None), "measurement", None)
                row = meas.metadata.get("row", 0) if meas is not None else 0
                self._born[tr] = (self._scans, int(row))
        order = sorted(sure, key=lambda tr: self._born.get(tr, (self._scans, 0)))
        existing = list(self.confirmed())
        accepted: list[Any] = []
        for cand in order:
            z = self._pseudo_detection(cand)
            if any(self._in_gate(t, z) for t in existing) or any(
                self._in_gate(a, z) for a in accepted
            ):
                self.dropped += 1
                continue
            accepted.append(cand)
        self._born = {tr: self._born[tr] for tr in self.initiator.holding_tracks}
        return set(accepted)
