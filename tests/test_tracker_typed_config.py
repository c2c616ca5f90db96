"""The tracker's configuration objects cross into Rust as they are, read there by attribute:
a field of the wrong type is a TypeError naming its path, a count out of range a ValueError,
and the same configuration gives the same tracks whichever way its fields were spelt."""

from __future__ import annotations

import numpy as np
import pytest

from usvfast import tracking as T
from usvfast.kalman import ConstantVelocity, LinearModel, constant_velocity_2d

CV = constant_velocity_2d(0.1)
TRANSITION = np.array([[0.95, 0.05], [0.05, 0.95]])


def make(**kw):
    """A small JPDA tracker; `kw` replaces any constructor argument, `init` the initiator's."""
    init = {"prior_state": np.zeros(4), "prior_covariance": np.eye(4), **kw.pop("init", {})}
    args = {
        "motion_model": CV,
        "sensors": [T.Sensor.position(0.5)],
        "association": T.JPDA(0.9, 0.95, 0.01),
        "deleter": T.StepsSinceUpdate(3),
        "initiator": T.MultiMeasurementInitiator(**init),
        **kw,
    }
    return T.Tracker(**args)


def turn_imm(turn):
    return T.IMM([CV, turn], TRANSITION)


# (constructor arguments, the field path the TypeError must start with)
WRONG_TYPES = [
    ({"init": {"min_points": "2"}}, r"initiator\.min_points"),
    ({"init": {"min_points": 2.0}}, r"initiator\.min_points"),
    ({"init": {"min_points": True}}, r"initiator\.min_points"),
    ({"init": {"missed_distance": "far"}}, r"initiator\.missed_distance"),
    ({"init": {"measure": 3}}, r"initiator\.measure"),
    ({"init": {"include_all": "yes"}}, r"initiator\.include_all"),
    ({"init": {"updates_only": 1}}, r"initiator\.updates_only"),
    ({"init": {"diag_load": None}}, r"initiator\.diag_load"),
    ({"init": {"m_of_n": (2, "3")}}, r"initiator\.m_of_n"),
    ({"init": {"motion_model": "cv"}}, r"initiator\.motion_model"),
    ({"init": {"use_joseph_cov": "no"}}, r"initiator\.use_joseph_cov"),
    ({"init": {"symmetric_covariance": None}}, r"initiator\.symmetric_covariance"),
    ({"init": {"max_new_tentative": 1.5}}, r"initiator\.max_new_tentative"),
    ({"init": {"prior_state": "origin"}}, r"prior_state"),
    ({"init": {"prior_covariance": np.eye(4) * 1j}}, r"prior_covariance"),
    ({"init": {"deleter": T.StepsSinceUpdate("3")}}, r"initiator\.deleter\.steps"),
    ({"init": {"deleter": "never"}}, r"initiator\.deleter: expected"),
    ({"deleter": T.AnyOf(T.StepsSinceUpdate(3), "never")}, r"deleter\.deleters: expected"),
    ({"deleter": T.AllOf(T.CovarianceTrace("big"))}, r"deleter\.deleters\.threshold"),
    ({"deleter": T.CovarianceTrace(1.0, mapping=[0.5])}, r"deleter\.mapping"),
    ({"deleter": T.TimeSinceUpdate("1 s")}, r"deleter\.seconds"),
    ({"deleter": (("steps", 3),)}, r"deleter: expected"),
    ({"motion_model": (ConstantVelocity("q"), ConstantVelocity(0.1))}, r"motion_model\.noise"),
    ({"motion_model": LinearModel(np.eye(4), np.eye(4))}, r"motion_model: a LinearModel"),
    ({"imm": turn_imm(T.KnownTurnRate("q", 0.1))}, r"imm\.modes\.q"),
    ({"imm": turn_imm(T.KnownTurnRate(0.1, "fast"))}, r"imm\.modes\.omega"),
    ({"imm": turn_imm(ConstantVelocity(None))}, r"imm\.modes\.noise_diff_coeff"),
    ({"imm": T.IMM([CV, CV], "sticky")}, r"imm\.transition"),
    ({"imm": T.IMM([CV, CV], TRANSITION, ["a", "b"])}, r"imm\.initial"),
    ({"existence": T.Existence(survival="high")}, r"existence\.survival"),
    ({"existence": T.Existence(confirm="yes")}, r"existence\.confirm"),
    ({"sensors": [T.Sensor("H", np.eye(2))]}, r"sensors\[0\]\.measurement_matrix"),
    (
        {"sensors": [T.Sensor.position(0.5), T.Sensor(np.eye(2, 4), np.eye(2), "H")]},
        r"sensors\[1\]\.initiation_matrix",
    ),
    (
        {"sensors": [T.Sensor(np.eye(2, 4), np.eye(2), polar=T.BearingRange((0, "2")))]},
        r"sensors\[0\]\.polar\.mapping",
    ),
    (
        {"sensors": [T.Sensor(np.eye(2, 4), np.eye(2), polar=T.BearingRange(alpha="x"))]},
        r"sensors\[0\]\.polar\.alpha",
    ),
]


@pytest.mark.parametrize(("kw", "path"), WRONG_TYPES, ids=[p for _, p in WRONG_TYPES])
def test_a_wrong_field_type_is_a_type_error_naming_the_field(kw, path):
    with pytest.raises(TypeError, match="^" + path):
        make(**kw)


OUT_OF_RANGE = [
    ({"init": {"min_points": -1}}, r"initiator\.min_points"),
    ({"init": {"min_points": 10**20}}, r"initiator\.min_points"),
    ({"init": {"max_new_tentative": 2**64}}, r"initiator\.max_new_tentative"),
    ({"init": {"m_of_n": (-2, 3)}}, r"initiator\.m_of_n"),
    ({"deleter": T.AnyOf(T.StepsSinceUpdate(-1))}, r"deleter\.deleters\.steps"),
    ({"deleter": T.CovarianceTrace(1.0, [-1])}, r"deleter\.mapping"),
    (
        {"sensors": [T.Sensor(np.eye(2, 4), np.eye(2), polar=T.BearingRange((0, -2)))]},
        r"sensors\[0\]\.polar\.mapping",
    ),
]


@pytest.mark.parametrize(("kw", "path"), OUT_OF_RANGE, ids=[p for _, p in OUT_OF_RANGE])
def test_a_count_out_of_range_is_a_value_error_naming_the_field(kw, path):
    with pytest.raises(ValueError, match="^" + path):
        make(**kw)


def test_array_checks_keep_their_error_types():
    from usvfast._core import DimensionError, NonFiniteError

    with pytest.raises(NonFiniteError, match=r"sensors\[0\]\.measurement_noise"):
        make(sensors=[T.Sensor(np.eye(2, 4), np.full((2, 2), np.nan))])
    with pytest.raises(DimensionError, match="prior_covariance"):
        make(init={"prior_covariance": np.ones(4)})
    with pytest.raises(TypeError, match=r"sensor\.measurement_matrix"):
        make().add_sensor(T.Sensor([["a", "b"]], np.eye(1)))


def test_spellings_of_the_same_configuration_track_alike():
    # Lists, integer arrays, numpy integers and a column prior state (Stone Soup's
    # StateVector) are the same configuration as float arrays: same tracks, bit for bit.
    rng = np.random.default_rng(3)
    scans = [
        (float(k), np.array([[k * 1.0, 2.0], [5.0, -k * 0.5]]) + rng.normal(0, 0.3, (2, 2)))
        for k in range(12)
    ]
    imm = T.IMM([CV, T.KnownTurnRate(0.1, 0.05)], TRANSITION)
    a = make(
        imm=imm,
        existence=T.Existence(),
        deleter=T.AnyOf(T.CovarianceTrace(50.0, (0, 2)), T.StepsSinceUpdate(3)),
        init={"min_points": 2, "m_of_n": None, "max_new_tentative": 10},
    )
    b = make(
        imm=T.IMM(
            [CV, T.KnownTurnRate((0.1, 0.1), 0.05)], TRANSITION.tolist(), np.array([0.5, 0.5])
        ),
        existence=T.Existence(),
        deleter=T.AnyOf(T.CovarianceTrace(50, np.array([0, 2])), T.StepsSinceUpdate(np.int64(3))),
        init={
            "prior_state": np.zeros((4, 1)),
            "prior_covariance": np.eye(4, dtype=int).tolist(),
            "min_points": np.int32(2),
            "max_new_tentative": np.uint8(10),
        },
    )
    for t, z in scans:
        ta, tb = a.step(t, z), b.step(t, z)
        assert np.array_equal(ta.ids, tb.ids)
        assert np.array_equal(ta.states, tb.states)
        assert np.array_equal(ta.mode_probabilities, tb.mode_probabilities)
        assert np.array_equal(ta.existence, tb.existence)
    assert len(a.tracks) == 2
