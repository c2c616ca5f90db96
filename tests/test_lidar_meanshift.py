"""Rust flat-kernel mean shift == scikit-learn's MeanShift (centres in order, labels)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from sklearn.cluster import MeanShift

from usvfast import DimensionError, NonFiniteError
from usvfast.lidar import mean_shift


def sklearn_fit(x, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # sklearn's bin-seeding fallback note
        model = MeanShift(**kw).fit(x)
    return model.cluster_centers_, model.labels_


def assert_same(x, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        centers, labels = mean_shift(x, **kw)
    ref_centers, ref_labels = sklearn_fit(x, **kw)
    assert centers.shape == ref_centers.shape
    np.testing.assert_allclose(centers, ref_centers, rtol=0, atol=1e-9)
    np.testing.assert_array_equal(labels, ref_labels)
    assert labels.dtype == np.int64
    return centers, labels


def test_sklearn_docstring_example():
    x = np.array([[1, 1], [2, 1], [1, 0], [4, 7], [3, 5], [3, 6]], float)
    _, labels = assert_same(x, bandwidth=2.0)
    np.testing.assert_array_equal(labels, [1, 1, 1, 0, 0, 0])


@st.composite
def clouds(draw):
    seed = draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    dim = draw(st.sampled_from([2, 3]))
    n = draw(st.integers(1, 80))
    if draw(st.booleans()):  # clustered: floating objects plus surface noise
        k = draw(st.integers(1, 8))
        centres = rng.uniform(-10, 10, (k, dim))
        x = centres[rng.integers(0, k, n)] + rng.normal(0, rng.uniform(0.05, 1.5), (n, dim))
    else:
        x = rng.uniform(-10, 10, (n, dim))
    params = {
        "bandwidth": draw(st.sampled_from([0.5, 1.0, 2.0, 3.7])),
        "bin_seeding": draw(st.booleans()),
        "cluster_all": draw(st.booleans()),
        "min_bin_freq": draw(st.integers(1, 3)),
        "max_iter": draw(st.sampled_from([0, 1, 5, 300])),
    }
    return x, params


# scikit-learn takes up to ~0.5 s per fit here: fewer examples than the profile's default.
@settings(max_examples=25)
@given(clouds())
def test_equals_sklearn_on_random_clouds(cloud):
    x, params = cloud
    try:
        ref = sklearn_fit(x, **params)
    except ValueError:  # no seed near any point (min_bin_freq too high): we raise too
        with pytest.raises(ValueError, match="seeds"), warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)
            mean_shift(x, **params)
        return
    centers, _ = assert_same(x, **params)
    assert len(centers) == len(ref[0])


@settings(max_examples=10)
@given(st.integers(0, 2**32 - 1), st.booleans())
def test_equals_sklearn_with_given_seeds(seed, cluster_all):
    rng = np.random.default_rng(seed)
    x = rng.normal(0, 3, (60, 2))
    seeds = rng.uniform(-6, 6, (10, 2))
    assert_same(x, bandwidth=1.5, seeds=seeds, cluster_all=cluster_all)


def test_orphans_are_labelled_minus_one_without_cluster_all():
    rng = np.random.default_rng(3)
    blob = rng.normal(0, 0.2, (30, 2))
    x = np.vstack([blob, [[20.0, 20.0]]])
    centers, labels = assert_same(
        x, bandwidth=2.0, bin_seeding=True, min_bin_freq=5, cluster_all=False
    )
    assert centers.shape == (1, 2)
    assert labels[-1] == -1 and (labels[:-1] == 0).all()
    _, labels = assert_same(x, bandwidth=2.0, bin_seeding=True, min_bin_freq=5, cluster_all=True)
    assert labels[-1] == 0


def test_bin_seeding_fallback_warns_like_sklearn():
    x = np.array([[0.0, 0.0], [10.0, 0.0], [0.0, 10.0]])
    with pytest.warns(UserWarning, match="Binning data failed"):
        mean_shift(x, bandwidth=1.0, bin_seeding=True)


def test_sklearn_backend_and_empty_input():
    x = np.random.default_rng(0).normal(0, 1, (50, 2))
    a = mean_shift(x, backend="rust")
    b = mean_shift(x, backend="sklearn")
    np.testing.assert_allclose(a[0], b[0], atol=1e-9)
    np.testing.assert_array_equal(a[1], b[1])
    for backend in ("rust", "sklearn"):
        centers, labels = mean_shift(np.zeros((0, 2)), backend=backend)
        assert centers.shape == (0, 2) and labels.shape == (0,)


def test_bad_input_names_the_argument():
    x = np.zeros((3, 2))
    with pytest.raises(NonFiniteError, match="points"):
        mean_shift([[np.nan, 0.0]])
    with pytest.raises(DimensionError, match="points"):
        mean_shift(np.zeros(3) + 1)
    with pytest.raises(DimensionError, match="seeds"):
        mean_shift(x, seeds=np.zeros((2, 3)))
    with pytest.raises(NonFiniteError, match="seeds"):
        mean_shift(x, seeds=[[np.inf, 0.0]])
    for bad in (0.0, -1.0, np.nan, np.inf):
        with pytest.raises(ValueError, match="bandwidth"):
            mean_shift(x, bandwidth=bad)
    with pytest.raises(ValueError, match="min_bin_freq"):
        mean_shift(x, min_bin_freq=0)
    with pytest.raises(ValueError, match="max_iter"):
        mean_shift(x, max_iter=-1)
    with pytest.raises(TypeError, match="max_iter"):
        mean_shift(x, max_iter=1.5)
    with pytest.raises(ValueError, match="backend"):
        mean_shift(x, backend="torch")
    with pytest.raises(ValueError, match="seeds"):
        mean_shift(x, seeds=[[50.0, 50.0]])
    with pytest.raises(ValueError, match="seeds"):
        mean_shift(x, seeds=[[50.0, 50.0]], backend="sklearn")


@pytest.mark.parametrize("dim", [1, 4])
@pytest.mark.parametrize("cluster_all", [True, False])
def test_equals_sklearn_in_other_dimensions(dim, cluster_all):
    # 1-D uses the grid; more than 3 dimensions use the plain scan.
    x = np.random.default_rng(dim).normal(0, 2, (120, dim))
    assert_same(x, bandwidth=1.5, cluster_all=cluster_all)
