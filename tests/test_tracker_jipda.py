"""Joint existence (JIPDA with visibility, `Existence(joint=True)`): the tracker against an
independent numpy oracle that enumerates every joint event of a cluster — the association of
detections to tracks and each track's state (no target / exists visible / exists unseen) — and
reads the posterior existence, visibility, association probabilities given existence and the
mixture state off the sums; a lone track against the IPDA closed form and Stone Soup's
`BernoulliParticleUpdater`; the direction of the change against IPDA; invariants."""

from __future__ import annotations

import dataclasses
import itertools
import pickle
from datetime import datetime

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.stats import chi2, multivariate_normal

from usvfast import tracking as T
from usvfast.kalman import constant_velocity_2d
from usvfast.trackcmd import load_config, tracker_from_config

Q, SIGMA = 0.1, 0.5
H = np.array([[1.0, 0, 0, 0], [0, 0, 1.0, 0]])


def tracker(pd, pg, lam, existence, method="ehm", max_hypotheses=None, imm=None):
    return T.Tracker(
        motion_model=constant_velocity_2d(Q),
        sensors=[T.Sensor.position(SIGMA)],
        association=T.JPDA(pd, pg, lam, method=method, max_hypotheses=max_hypotheses),
        deleter=T.StepsSinceUpdate(1000),
        initiator=T.MultiMeasurementInitiator(
            np.zeros(4), np.diag([0, 1.0, 0, 1.0]), missed_distance=2.0
        ),
        existence=existence,
        imm=imm,
    )


def cv_predict(x, p, dt=1.0):
    """Stone Soup's / usvfast's 2-D constant velocity, q = Q."""
    f1 = np.array([[1.0, dt], [0, 1.0]])
    q1 = Q * np.array([[dt**3 / 3, dt**2 / 2], [dt**2 / 2, dt]])
    f = np.kron(np.eye(2), f1)
    qm = np.kron(np.eye(2), q1)
    return f @ x, f @ p @ f.T + qm


def oracle(xs, ps, rv, z, pd, pg, lam, ex):
    """Every joint event (a, ε) of the predicted cluster, enumerated: a assigns each track a
    gated detection or none (no detection twice), ε_t ∈ {0 no target, 1 visible, 2 unseen}
    with prior (1 − r⁻, r⁻v⁻, r⁻(1 − v⁻)); weight Π prior · g with g(0, visible) = 1 − P_D P_G,
    g(0, other) = 1, g(j, visible) = P_D N(z_j)/λ, g(j, other) = 0. Returns per track the
    posterior existence, visibility, P(a = j | exists) (j = 0 missed) and the mixture given
    existence."""
    nt, nd = len(xs), len(z)
    gate = chi2.ppf(pg, 2)
    preds = [cv_predict(x, p) for x, p in zip(xs, ps, strict=True)]
    c = np.zeros((nt, nd))
    upd = []
    for t, (x, p) in enumerate(preds):
        s = H @ p @ H.T + SIGMA**2 * np.eye(2)
        k = p @ H.T @ np.linalg.inv(s)
        row = []
        for j in range(nd):
            y = z[j] - H @ x
            if y @ np.linalg.solve(s, y) <= gate:
                c[t, j] = pd * multivariate_normal(H @ x, s).pdf(z[j]) / lam
            row.append((x + k @ y, p - k @ s @ k.T))
        upd.append(row)
    r0 = np.array([ex.survival * r for r, _ in rv])
    v0 = np.array([v * ex.vis_stay + (1 - v) * (1 - ex.invis_stay) for _, v in rv])
    prior = np.stack([1 - r0, r0 * v0, r0 * (1 - v0)], axis=1)  # (nt, 3)
    g = np.zeros((nt, nd + 1, 3))
    g[:, 0] = [1.0, 1 - pd * pg, 1.0]
    g[:, 1:, 1] = c
    a = np.array(list(itertools.product(range(nd + 1), repeat=nt))).reshape(-1, nt)
    ok = np.array([len(set(r[r > 0])) == np.count_nonzero(r) for r in a])
    a = a[ok]
    e = np.array(list(itertools.product(range(3), repeat=nt))).reshape(-1, nt)
    w = np.ones((len(a), len(e)))
    for t in range(nt):
        w *= prior[t][e[:, t]][None, :] * g[t][a[:, t][:, None], e[:, t][None, :]]
    w /= w.sum()
    out = []
    for t in range(nt):
        exists = e[:, t] != 0
        r1 = w[:, exists].sum()
        v1 = w[:, e[:, t] == 1].sum() / r1
        beta = np.array([w[a[:, t] == j][:, exists].sum() for j in range(nd + 1)]) / r1
        x, p = preds[t]
        comps = [(x, p)] + upd[t]
        mean = sum(b * xc for b, (xc, _) in zip(beta, comps, strict=True))
        cov = sum(
            b * (pc + np.outer(xc - mean, xc - mean))
            for b, (xc, pc) in zip(beta, comps, strict=True)
        )
        gated = [j for j in range(nd) if c[t, j] > 0 or _gated(preds[t], z[j], gate)]
        out.append((r1, v1, beta, mean, cov, gated))
    return out


def _gated(pred, zj, gate):
    x, p = pred
    s = H @ p @ H.T + SIGMA**2 * np.eye(2)
    y = zj - H @ x
    return y @ np.linalg.solve(s, y) <= gate


def scene(rng, nt, nd):
    """`nt` tracks within a few metres (shared gates) and `nd` detections among them."""
    xs = [
        np.array([rng.normal(0, 1.0), rng.normal(1, 0.3), rng.normal(0, 1.0), rng.normal(0, 0.3)])
        for _ in range(nt)
    ]
    ps = []
    for _ in range(nt):
        a = rng.normal(0, 0.4, (4, 4))
        ps.append(a @ a.T + np.diag([0.3, 0.1, 0.3, 0.1]))
    z = (np.array([1.0, 0.0]) + rng.normal(0, 1.2, (nd, 2))).reshape(nd, 2)
    return xs, ps, z


def params(rng):
    pd = rng.uniform(0.3, 0.98)
    pg = rng.uniform(0.9, 0.999)
    lam = 10 ** rng.uniform(-3, -0.5)
    ex = T.Existence(
        survival=rng.uniform(0.8, 1.0),
        delete=0.0,
        vis_stay=rng.uniform(0.5, 1.0),
        invis_stay=rng.uniform(0.0, 0.9),
        joint=True,
    )
    return pd, pg, lam, ex


@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 2**31),
    nt=st.integers(2, 4),
    nd=st.integers(0, 5),
    method=st.sampled_from(["ehm", "brute_force"]),
)
def test_jipda_equals_the_enumeration_of_every_joint_event(seed, nt, nd, method):
    rng = np.random.default_rng(seed)
    pd, pg, lam, ex = params(rng)
    xs, ps, z = scene(rng, nt, nd)
    rv = [(rng.uniform(0.01, 1.0), rng.uniform(0.0, 1.0)) for _ in range(nt)]
    tr = tracker(pd, pg, lam, ex, method=method)
    for x, p, (r, v) in zip(xs, ps, rv, strict=True):
        tr.add_track(x, p, 0.0, existence=r, visibility=v)
    got = tr.step(1.0, z)
    want = oracle(xs, ps, rv, z, pd, pg, lam, ex)
    for i, (r1, v1, beta, mean, cov, gated) in enumerate(want):
        np.testing.assert_allclose(got.existence[i], r1, rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(got.visibility[i], v1, rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(got.missed_probability[i], beta[0], rtol=1e-9, atol=1e-12)
        a, b = got.assoc_offsets[i], got.assoc_offsets[i + 1]
        assert sorted(got.assoc_detection[a:b].tolist()) == gated
        for d, prob in zip(got.assoc_detection[a:b], got.assoc_probability[a:b], strict=True):
            np.testing.assert_allclose(prob, beta[d + 1], rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(got.states[i], mean, rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(got.covariances[i], cov, rtol=1e-9, atol=1e-9)


def test_a_chain_cluster_by_belief_propagation_equals_the_enumeration():
    """Belief propagation (a budget of 1 sends every cluster there) is exact on a tree: three
    tracks in a row, each pair of neighbours sharing one detection."""
    pd, pg, lam, ex = 0.8, 0.99, 0.02, T.Existence(0.95, vis_stay=0.9, invis_stay=0.5, joint=True)
    xs = [np.array([0.0, 1, 3.0 * i, 0]) for i in range(3)]
    ps = [np.diag([0.3, 0.1, 0.3, 0.1])] * 3
    z = np.array([[1.0, 1.5], [1.1, 4.4]])
    rv = [(0.9, 0.8), (0.3, 0.6), (0.7, 1.0)]
    want = oracle(xs, ps, rv, z, pd, pg, lam, ex)
    assert [w[5] for w in want] == [[0], [0, 1], [1]]
    for method, budget in (("ehm", 1), ("lbp", None)):
        tr = tracker(pd, pg, lam, ex, method=method, max_hypotheses=budget)
        for x, p, (r, v) in zip(xs, ps, rv, strict=True):
            tr.add_track(x, p, 0.0, existence=r, visibility=v)
        got = tr.step(1.0, z)
        assert tr.last_step.approximated_clusters == 1
        np.testing.assert_allclose(got.existence, [w[0] for w in want], rtol=1e-10)
        np.testing.assert_allclose(got.visibility, [w[1] for w in want], rtol=1e-10)
        np.testing.assert_allclose(got.states, [w[3] for w in want], rtol=1e-10, atol=1e-10)


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**31), nd=st.integers(0, 5), visible=st.booleans())
def test_one_track_jipda_is_the_ipda_closed_form(seed, nd, visible):
    """A lone track: JIPDA's r⁺, v⁺ are those of the per-track IPDA (1e-12); with v⁻ = 1 its
    state, covariance and association probabilities too; with v⁻ < 1 its state weights are
    1 − P_D P_G v⁻ : v⁻ P_D N/λ (the missed hypothesis also covers an unseen target)."""
    rng = np.random.default_rng(seed)
    pd, pg, lam, ex = params(rng)
    if visible:
        ex = dataclasses.replace(ex, vis_stay=1.0)
    xs, ps, z = scene(rng, 1, nd)
    r, v = rng.uniform(0.01, 1.0), 1.0 if visible else rng.uniform(0.0, 1.0)
    ipda, jipda = (
        tracker(pd, pg, lam, dataclasses.replace(ex, joint=joint)) for joint in (False, True)
    )
    out = []
    for tr in (ipda, jipda):
        tr.add_track(xs[0], ps[0], 0.0, existence=r, visibility=v)
        out.append(tr.step(1.0, z))
    a, b = out
    np.testing.assert_allclose(b.existence, a.existence, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(b.visibility, a.visibility, rtol=1e-12, atol=1e-15)
    if visible:
        np.testing.assert_allclose(b.states, a.states, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(b.covariances, a.covariances, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(b.missed_probability, a.missed_probability, rtol=1e-12)
        np.testing.assert_allclose(b.assoc_probability, a.assoc_probability, rtol=1e-12)
    # Both against the enumeration oracle (which holds for v⁻ < 1 too).
    r1, v1, beta, mean, _, _ = oracle(xs, ps, [(r, v)], z, pd, pg, lam, ex)[0]
    np.testing.assert_allclose(b.existence[0], r1, rtol=1e-9)
    np.testing.assert_allclose(b.visibility[0], v1, rtol=1e-9)
    np.testing.assert_allclose(b.missed_probability[0], beta[0], rtol=1e-9)
    np.testing.assert_allclose(b.states[0], mean, rtol=1e-9, atol=1e-9)


def test_one_track_runs_of_jipda_and_ipda_are_identical_when_visible():
    """Scans of a target in clutter (v stays 1), the clutter 30-70 m away so the target's track
    is alone in its cluster: the same states, existences and mode probabilities for that track,
    with the constant-velocity model and with an IMM."""
    rng = np.random.default_rng(3)
    zs = []
    for k in range(30):
        clutter = rng.uniform([-20 + k, 30], [20 + k, 70], (rng.integers(0, 4), 2))
        tgt = [[k + rng.normal(0, 0.5), rng.normal(0, 0.5)]] if rng.random() < 0.8 else []
        zs.append(np.vstack([np.array(tgt).reshape(-1, 2), clutter]))
    imm = T.IMM([constant_velocity_2d(0.05), constant_velocity_2d(1.0)], [[0.95, 0.05], [0.1, 0.9]])
    for bank in (None, imm):
        runs = []
        for joint in (False, True):
            tr = tracker(0.8, 0.99, 0.005, T.Existence(0.99, delete=0.01, joint=joint), imm=bank)
            tr.add_track([0, 1, 0, 0], np.diag([1.0, 0.5, 1.0, 0.5]), -1.0)
            hist = []
            for k, z in enumerate(zs):
                t = tr.step(float(k), z)
                assert t.ids[0] == 0
                hist.append((t.states[0], t.existence[0], t.visibility[0], t.mode_probabilities[0]))
            runs.append(hist)
        for (sa, ea, va, ma), (sb, eb, vb, mb) in zip(*runs, strict=True):
            np.testing.assert_allclose(sb, sa, rtol=1e-12, atol=1e-10)
            np.testing.assert_allclose(eb, ea, rtol=1e-12, atol=1e-15)
            assert va == vb == 1.0
            np.testing.assert_allclose(mb, ma, rtol=1e-12, atol=1e-15)


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 2**31), nd=st.integers(1, 4))
def test_one_track_existence_equals_stonesoup_bernoulli_update(seed, nd):
    """Stone Soup's `BernoulliParticleUpdater` (Ristic et al. 2013) on one particle at the
    predicted state with the innovation covariance S as its measurement noise: its existence
    update (1 − Δ) r / (1 − r Δ), Δ = P_D − Σ P_D N(z; ẑ, S)/λ, is the JIPDA of one visible
    track with P_G = 1."""
    from stonesoup.models.measurement.linear import LinearGaussian
    from stonesoup.types.detection import Detection
    from stonesoup.types.hypothesis import SingleHypothesis
    from stonesoup.types.multihypothesis import MultipleHypothesis
    from stonesoup.types.prediction import BernoulliParticleStatePrediction
    from stonesoup.updater.particle import BernoulliParticleUpdater

    rng = np.random.default_rng(seed)
    pd, lam = rng.uniform(0.3, 0.95), 10 ** rng.uniform(-3, -1)
    xs, ps, z = scene(rng, 1, nd)
    r = rng.uniform(0.05, 1.0)
    tr = tracker(pd, 1.0, lam, T.Existence(1.0, delete=0.0, joint=True))
    tr.add_track(xs[0], ps[0], 0.0, existence=r)
    got = tr.step(1.0, z)

    x, p = cv_predict(xs[0], ps[0])
    s = H @ p @ H.T + SIGMA**2 * np.eye(2)
    epoch = datetime(2024, 1, 1)
    pred = BernoulliParticleStatePrediction(
        state_vector=x.reshape(4, 1),
        log_weight=np.array([0.0]),
        existence_probability=r,
        timestamp=epoch,
    )
    model = LinearGaussian(4, [0, 2], s)
    hyps = MultipleHypothesis(
        [
            SingleHypothesis(pred, Detection(zi.reshape(2, 1), epoch, measurement_model=model))
            for zi in z
        ]
    )
    upd = BernoulliParticleUpdater(
        measurement_model=model, detection_probability=pd, clutter_rate=1, clutter_distribution=lam
    )
    want = upd.update(hyps).existence_probability
    np.testing.assert_allclose(got.existence[0], float(want), rtol=1e-10)


def two_rivals(joint):
    """Tracks A (r = 0.95) and B (r = 0.1) 1 m apart, one detection between them (nearer B)."""
    tr = tracker(0.9, 0.99, 0.01, T.Existence(1.0, delete=0.0, joint=joint))
    p = np.diag([0.5, 0.1, 0.5, 0.1])
    tr.add_track([-1.0, 1, 0, 0], p, 0.0, existence=0.95)  # A, predicted at n = 0
    tr.add_track([0.0, 1, 0, 0], p, 0.0, existence=0.1)  # B, predicted at n = 1
    return tr.step(1.0, [[0.6, 0.0]])


def test_a_doubtful_track_yields_its_detection_to_a_sure_one():
    ipda, jipda = two_rivals(False), two_rivals(True)
    # A takes the detection more under JIPDA (B probably does not exist to compete) ...
    assert jipda.assoc_probability[0] > ipda.assoc_probability[0] + 0.1
    assert abs(jipda.states[0, 0] - 0.6) < abs(ipda.states[0, 0] - 0.6)
    # ... and B's existence falls below its prior 0.1 (the detection is A's, and B, if it
    # existed, would likely have been seen), where IPDA credits B with the whole detection too.
    assert jipda.existence[1] < 0.1 < 0.5 < ipda.existence[1]
    # A stays sure either way (IPDA counts the detection for both tracks: a little higher).
    assert 0.98 < jipda.existence[0] < ipda.existence[0]


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**31), method=st.sampled_from(["ehm", "brute_force", "lbp"]))
def test_existence_visibility_marginals_and_covariances_stay_valid(seed, method):
    rng = np.random.default_rng(seed)
    pd, pg, lam, ex = params(rng)
    ex = dataclasses.replace(ex, delete=0.02)
    tr = tracker(pd, pg, lam, ex, method=method)
    targets = rng.uniform(-5, 5, (4, 2))
    for k in range(15):
        seen = targets[rng.random(4) < pd]
        z = np.vstack([seen + rng.normal(0, SIGMA, seen.shape), rng.uniform(-8, 8, (3, 2))])
        t = tr.step(float(k), z)
        targets[:, 0] += 0.5
        assert np.all((t.existence >= 0) & (t.existence <= 1))
        assert np.all((t.visibility >= 0) & (t.visibility <= 1))
        for i in range(len(t)):
            a, b = t.assoc_offsets[i], t.assoc_offsets[i + 1]
            total = t.missed_probability[i] + t.assoc_probability[a:b].sum()
            assert abs(total - 1.0) < 1e-12
            c = t.covariances[i]
            np.testing.assert_allclose(c, c.T, atol=1e-12)
            assert np.linalg.eigvalsh(c).min() > 0


def test_joint_is_a_validated_option_of_existence_and_the_toml():
    with pytest.raises(TypeError, match=r"existence\.joint"):
        tracker(0.9, 0.99, 0.01, T.Existence(joint=1))
    tr = tracker(0.9, 0.99, 0.01, None)
    with pytest.raises(ValueError, match="existence"):
        tr.add_track(np.zeros(4), np.eye(4), 0.0, existence=0.5)
    tr = tracker(0.9, 0.99, 0.01, T.Existence(joint=True))
    for bad in ({"existence": 0.0}, {"existence": 1.5}, {"existence": 0.5, "visibility": -0.1}):
        with pytest.raises(ValueError, match=r"^(existence|visibility):"):
            tr.add_track(np.zeros(4), np.eye(4), 0.0, **bad)
    with pytest.raises(ValueError, match="visibility"):
        tr.add_track(np.zeros(4), np.eye(4), 0.0, visibility=0.5)
    with pytest.raises(TypeError, match="existence"):
        tr.add_track(np.zeros(4), np.eye(4), 0.0, existence="high")
    # The TOML key: `joint = true` changes a run (visibility < 1 after a missed scan), an
    # explicit `joint = false` is the default.
    cfg = load_config("joyride")
    rng = np.random.default_rng(2)
    zs = [np.array([[10.0 * k, 5.0 * k]]) + rng.normal(0, 8.0, 2) for k in range(20)]
    zs[8] = np.zeros((0, 2))
    runs = []
    for joint in (None, False, True):
        ex = dict(cfg["existence"]) if joint is None else {**cfg["existence"], "joint": joint}
        tr = tracker_from_config({**cfg, "existence": ex})
        runs.append(np.vstack([tr.step(float(k), z).states for k, z in enumerate(zs)]))
    assert len(runs[0]) > 10
    np.testing.assert_array_equal(runs[0], runs[1])
    assert not np.allclose(runs[0], runs[2])
    with pytest.raises(ValueError, match=r"tracker\.existence\.joint"):
        tracker_from_config({**cfg, "existence": {**cfg["existence"], "joint": "yes"}})


def test_a_joint_tracker_pickles_and_continues_identically():
    rng = np.random.default_rng(1)
    tr = tracker(0.9, 0.99, 0.01, T.Existence(0.99, vis_stay=0.9, invis_stay=0.6, joint=True))
    for k in range(5):
        tr.step(float(k), rng.uniform([k - 3, -3], [k + 3, 3], (4, 2)))
    copy = pickle.loads(pickle.dumps(tr))
    z = rng.uniform([2, -3], [8, 3], (4, 2))
    a, b = tr.step(5.0, z), copy.step(5.0, z)
    assert len(a) > 0
    np.testing.assert_array_equal(a.states, b.states)
    np.testing.assert_array_equal(a.existence, b.existence)


def test_tracks_that_cannot_exist_get_the_limit_of_lone_tracks():
    """survival = 0 makes every r⁻ = 0: r⁺ = 0, and each state given existence is the limit
    r⁻ → 0, where no other track of the cluster can take a detection: a lone track's weights
    1 − P_D P_G v⁻ : v⁻ P_D N/λ (with v⁻ = 1 the PDA update, i.e. the track tracked alone)."""
    rng = np.random.default_rng(4)
    xs, ps, z = scene(rng, 2, 3)
    tr = tracker(0.9, 0.99, 0.01, T.Existence(0.0, delete=0.0, joint=True))
    for x, p in zip(xs, ps, strict=True):
        tr.add_track(x, p, 0.0, existence=0.5)
    got = tr.step(1.0, z)
    assert got.assoc_offsets[-1] == 6  # every detection in both gates: one cluster
    np.testing.assert_array_equal(got.existence, [0.0, 0.0])
    for i, (x, p) in enumerate(zip(xs, ps, strict=True)):
        alone = tracker(0.9, 0.99, 0.01, T.Existence(0.0, delete=0.0))
        alone.add_track(x, p, 0.0, existence=0.5)
        want = alone.step(1.0, z)
        np.testing.assert_allclose(got.states[i], want.states[0], rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(got.missed_probability[i], want.missed_probability[0])
