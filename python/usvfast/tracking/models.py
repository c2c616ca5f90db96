"""Motion-model banks and track existence of `usvfast.tracking.Tracker`: known-rate and
estimated-rate coordinated turns, the IMM and the IPDA / JIPDA existence settings."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

from usvfast.kalman import MotionModel


@dataclass(frozen=True)
class KnownTurnRate:
    """Coordinated turn at a known rate `omega` (rad/s) on [n, v_n, e, v_e] — Stone Soup's
    `KnownTurnRate(turn_noise_diff_coeffs=(q, q), turn_rate=omega)`: exact transition of a
    constant turn (positive omega turns from north towards east, i.e. to starboard), Wiener
    velocity noise q (m² s⁻³) per axis (`q` a float or (q_n, q_e)). An IMM mode."""

    q: float | tuple[float, float]
    omega: float


def _noise_coeff(name: str, v: Any) -> float:
    """`v` as a finite float >= 0, else TypeError/ValueError naming `name`."""
    if isinstance(v, bool) or not isinstance(v, int | float | np.integer | np.floating):
        raise TypeError(f"{name}: expected a float, got {type(v).__name__}")
    if not (np.isfinite(v) and v >= 0):
        raise ValueError(f"{name}: must be finite and >= 0, got {v!r}")
    return float(v)


@dataclass(frozen=True)
class ConstantTurn:
    """Coordinated turn with the turn rate in the state [n, v_n, e, v_e, ω] (ω rad/s, positive
    from north towards east, i.e. to starboard) — Stone Soup's
    `ConstantTurn(linear_noise_coeffs=(q, q), turn_noise_coeff=q_turn)`: exact transition of a
    constant turn (ω → 0 is the constant-velocity limit, no division by zero), process noise
    block_diag(q_n Q, q_e Q, q_turn dt), Q = [[dt³/3, dt²/2], [dt²/2, dt]]. An IMM mode of a
    5-D tracker, whose other modes are 5-D too (e.g. `constant_velocity_turn_rate(q, q_w)`).

    q: velocity noise (m² s⁻³), a float or (q_n, q_e); q_turn: turn-rate noise (rad² s⁻³);
    predictor: "ekf" (Stone Soup's `ExtendedKalmanPredictor`, here with the analytic Jacobian)
    or "ukf" (`UnscentedKalmanPredictor` with alpha, beta, kappa; kappa None: 3 − 5).
    Bad values raise ValueError (TypeError for a wrong type) naming the argument."""

    q: float | tuple[float, float]
    q_turn: float
    predictor: Literal["ekf", "ukf"] = "ekf"
    alpha: float = 0.5
    beta: float = 2.0
    kappa: float | None = None

    def __post_init__(self) -> None:
        if isinstance(self.q, tuple | list | np.ndarray):
            if len(self.q) != 2:
                raise ValueError(f"q: expected a float or (q_n, q_e), got {self.q!r}")
            q: Any = (_noise_coeff("q", self.q[0]), _noise_coeff("q", self.q[1]))
        else:
            q = _noise_coeff("q", self.q)
        object.__setattr__(self, "q", q)
        object.__setattr__(self, "q_turn", _noise_coeff("q_turn", self.q_turn))
        if self.predictor not in ("ekf", "ukf"):
            raise ValueError(f"predictor: expected 'ekf' or 'ukf', got {self.predictor!r}")
        for name in ("alpha", "beta") + (("kappa",) if self.kappa is not None else ()):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int | float | np.integer | np.floating):
                raise TypeError(f"{name}: expected a float, got {type(v).__name__}")
            if not np.isfinite(v):
                raise ValueError(f"{name}: must be finite, got {v!r}")
            object.__setattr__(self, name, float(v))
        if self.alpha <= 0:
            raise ValueError(f"alpha: must be > 0, got {self.alpha!r}")
        if self.kappa is not None and 5 + self.kappa <= 0:
            raise ValueError(f"kappa: 5 + kappa must be > 0, got {self.kappa!r}")


def constant_velocity_turn_rate(q: float, q_turn: float) -> MotionModel:
    """The constant-velocity model of a 5-D turn-rate state [n, v_n, e, v_e, ω]:
    [ConstantVelocity(q), ConstantVelocity(q), RandomWalk(q_turn)] (q m² s⁻³, q_turn
    rad² s⁻³): the tracker's model (tentative tracks) and the CV mode beside `ConstantTurn`
    in an IMM; ω is carried (as a random walk) so that every mode shares one state."""
    from usvfast.kalman import ConstantVelocity, RandomWalk

    q = _noise_coeff("q", q)
    return (ConstantVelocity(q), ConstantVelocity(q), RandomWalk(_noise_coeff("q_turn", q_turn)))


@dataclass(frozen=True)
class IMM:
    """Interacting multiple models for the confirmed tracks (Blom and Bar-Shalom 1988).

    modes: motion models over the tracker's state (usvfast.kalman models such as
    constant_velocity_2d(q), or `KnownTurnRate(q, omega)`; on the 5-D state [n, v_n, e, v_e,
    ω] `ConstantTurn(q, q_turn)` beside e.g. `constant_velocity_turn_rate(q, q_w)`);
    transition (r, r): Markov switching matrix, transition[i, j] = P(mode j at the next scan |
    mode i now), rows summing to 1;
    initial (r,): mode probabilities of a newly confirmed track (default uniform). Each scan:
    mixing, mode predictions, a mode-conditioned update (Kalman update under GNN, PDA mixture
    with the track's JPDA association weights under JPDA), mode probabilities from the mode
    likelihoods, and the moment-matched output state (which gating and association use in its
    predicted form Σ c̄_j N(x_j⁻, P_j⁻)). filterpy's `IMMEstimator` on a single target.
    Tentative tracks use the initiator's model unless `MultiMeasurementInitiator(imm=True)`
    runs the bank on them too; `Tracks.mode_probabilities` holds μ.
    """

    modes: Sequence[Any]
    transition: Any
    initial: Any = None


@dataclass(frozen=True)
class Existence:
    """Track existence with visibility for confirmed JPDA tracks (IPDA, Mušicki, Evans and
    Stanković 1994; the visibility chain of Brekke et al.'s VIMMJIPDA).

    Per track: r = P(target exists), v = P(visible | exists). Each scan r⁻ = survival·r,
    v⁻ = v·vis_stay + (1 − v)(1 − invis_stay); with the likelihood ratio of the scan
    L = 1 − P_D P_G + Σ_i P_D N(z_i; ẑ, S)/λ over the track's gated detections (the JPDA
    hypothesis weights), r⁺ = r⁻(v⁻L + 1 − v⁻) / (r⁻(v⁻L + 1 − v⁻) + 1 − r⁻) and
    v⁺ = v⁻L / (v⁻L + 1 − v⁻). A confirmed track starts at r = initial, v = 1 and is deleted
    once r < delete (besides `deleter`). The defaults vis_stay = 1, invis_stay = 0 keep v = 1
    (plain IPDA); vis_stay < 1 lets a target exist unseen (behind another ship) without losing
    its existence.

    joint: JIPDA (Mušicki and Evans, IEEE Trans. AES 40(3), 2004, with the VIMMJIPDA's
    visibility) for the confirmed tracks instead of the per-track IPDA: in each JPDA cluster a
    track's hypotheses are weighted by its predicted r⁻v⁻ — missed 1 − P_D P_G r⁻v⁻, detection
    r⁻v⁻ P_D N(z; ẑ, S)/λ — so a track that probably does not exist yields its detections to one
    that does; from the joint marginals β (β_0 missed) r⁺ = β_0 r⁻(1 − P_D P_G v⁻)/(1 − P_D P_G
    r⁻v⁻) + Σ_{j≥1} β_j, v⁺ = (β_0 r⁻v⁻(1 − P_D P_G)/(1 − P_D P_G r⁻v⁻) + Σ_{j≥1} β_j)/r⁺, and
    the state is the mixture with the association probabilities given existence
    (β_0 r⁻(1 − P_D P_G v⁻)/((1 − P_D P_G r⁻v⁻) r⁺) missed, β_j/r⁺), which also decide
    whether the state is an update and which detections are kept from the initiator, and
    which `Tracks`/`TrackHistory` report as missed_probability and assoc_probability. A track
    alone in its cluster gets the IPDA's r⁺ and v⁺; its state is the IPDA's PDA update when
    v⁻ = 1, and
    weights the missed hypothesis by 1 − P_D P_G v⁻ (against v⁻ P_D N/λ) when v⁻ < 1 (a target
    may exist unseen). Under an IMM the mode likelihoods are those given existence
    (1 − P_D P_G v⁻ + v⁻ Σ P_D N_mode(z)/λ). Default False (per-track IPDA, as before).

    confirm: confirmation by existence. Tentative tracks then start at r = birth, are updated
    each scan with the likelihood ratio of their GNN-assigned detection
    (L = 1 − P_D P_G + P_D N(z; ẑ, S)/λ, or 1 − P_D P_G when missed), are confirmed once the
    initiator would confirm them (min_points / M-of-N) and r >= confirm, dropped once
    r < delete, and keep their r when confirmed. None: the initiator alone confirms and
    confirmed tracks start at r = initial.
    """

    survival: float = 0.99
    initial: float = 0.9
    delete: float = 0.05
    vis_stay: float = 1.0
    invis_stay: float = 0.0
    confirm: float | None = None
    birth: float = 0.5
    joint: bool = False
