"""Where the Joyride tracking error comes from: the radar plots, compared with the target's
GNSS positions, are the true positions turned about the own ship by about -1.85 degrees (a
bearing bias: the radar's heading alignment), plus noise of ~11 m per axis. The bias is the
same in both halves of the recording, no time lag or offset on the target boat explains
anything beyond it, and it cannot be seen from the plots alone (their likelihood under a
Kalman filter does not change with it). Corrected by a bias measured on one half, the
unchanged `joyride` and `joyride-known-turns` presets meet every aim on the other half.

The helpers here are also used by benches/bench_tracker_joyride.py."""

from __future__ import annotations

import numpy as np
import pytest
from filterpy.kalman import KalmanFilter

from usvfast.datasets import load_joyride
from usvfast.metrics import track_quality
from usvfast.radar import bearing_bias_deg as radar_bearing_bias_deg
from usvfast.trackcmd import load_config, read_plots, run_tracking

from conftest import SHARED_DATA

JOYRIDE = SHARED_DATA / "joyride" / "joyride.mat"
HALF = 119  # first scan of the second half


def target_plot_errors(rec, gate: float = 60.0) -> tuple[np.ndarray, np.ndarray]:
    """(scans (n,), errors (n, 2) north/east m) of the plot nearest the GNSS truth in each
    scan that has one within `gate` metres (a diagnostic: it uses the truth)."""
    si, plots = rec.scan_arrays()
    truth = rec.target[:, [0, 2]]
    scans, errs = [], []
    for k in range(rec.n_scans):
        p = plots[si == k]
        if len(p):
            d = p - truth[k]
            j = int(np.argmin(np.hypot(d[:, 0], d[:, 1])))
            if np.hypot(*d[j]) <= gate:
                scans.append(k)
                errs.append(d[j])
    return np.array(scans), np.array(errs)


def error_terms(rec, scans: np.ndarray) -> dict[str, np.ndarray]:
    """Error shapes (n, 2) per unit parameter at each scan: a turn about the own ship (per
    radian, compass bearing +), a turn about the plane's origin, a constant north / east
    offset, an offset along / across the target's heading (m), and a time lag (per second:
    the target's velocity)."""
    truth, own = rec.target[scans][:, [0, 2]], rec.ownship[scans][:, [0, 2]]
    vel = rec.target[scans][:, [1, 3]]
    rel = truth - own
    along = vel / np.hypot(vel[:, 0], vel[:, 1])[:, None]
    one, zero = np.ones(len(scans)), np.zeros(len(scans))
    return {
        "turn about own ship": np.stack([-rel[:, 1], rel[:, 0]], axis=1),
        "turn about origin": np.stack([-truth[:, 1], truth[:, 0]], axis=1),
        "north offset": np.stack([one, zero], axis=1),
        "east offset": np.stack([zero, one], axis=1),
        "along target": along,
        "across target": np.stack([-along[:, 1], along[:, 0]], axis=1),
        "time lag": vel,
    }


def fit_errors(errors: np.ndarray, terms: list[np.ndarray]) -> tuple[np.ndarray, float]:
    """Least-squares parameters of `terms` for the errors (n, 2), and the RMS (m) of what is
    left."""
    y = np.concatenate([errors[:, 0], errors[:, 1]])
    if not terms:
        return np.zeros(0), float(np.sqrt(np.mean(errors[:, 0] ** 2 + errors[:, 1] ** 2)))
    a = np.concatenate(
        [np.stack([t[:, 0] for t in terms], 1), np.stack([t[:, 1] for t in terms], 1)]
    )
    sol = np.linalg.lstsq(a, y, rcond=None)[0]
    left = (y - a @ sol).reshape(2, -1)
    return sol, float(np.sqrt(np.mean(left[0] ** 2 + left[1] ** 2)))


def bearing_bias_deg(rec, lo: int = 0, hi: int | None = None) -> float:
    """The plots' bearing bias (degrees, plot minus truth) fitted on scans [lo, hi) against the
    GNSS truth (`usvfast.radar.bearing_bias_deg`, the calibration a deployment would run)."""
    si, plots = rec.scan_arrays()
    return radar_bearing_bias_deg(
        plots,
        si,
        rec.ownship[si][:, [0, 2]],
        rec.target[:, [0, 2]],
        scans=np.arange(lo, rec.n_scans if hi is None else hi),
    )


def track_plots(plots, res) -> dict[int, np.ndarray]:
    """Per scan, the plot nearest the longest track's estimate (within 40 m): the plots the
    tracker took for the target, found without the truth."""
    ids, counts = np.unique(res.track_id, return_counts=True)
    sel = res.track_id == ids[np.argmax(counts)]
    out = {}
    for k, x in zip(res.scan[sel], res.state[sel], strict=True):
        p = plots.plots[plots.scan_index == k]
        if len(p):
            d = np.hypot(p[:, 0] - x[0], p[:, 1] - x[2])
            if d.min() < 40.0:
                out[int(k)] = p[np.argmin(d)]
    return out


def plots_log_likelihood(
    plots, target: dict[int, np.ndarray], correction_deg: float, q: float = 1.0, sigma=12.0
) -> float:
    """Log-likelihood (filterpy's constant-velocity Kalman filter, noise diffusion q m² s⁻³,
    plot σ m per axis) of the target's plots turned by `correction_deg` about the own ship."""
    c, s = np.cos(np.radians(correction_deg)), np.sin(np.radians(correction_deg))
    first = {int(k): o for k, o in zip(plots.scan_index, plots.origins, strict=True)}
    kf, last, total = None, 0.0, 0.0
    for k in sorted(target):
        o = first[k]
        r = target[k] - o
        z = o + np.array([c * r[0] - s * r[1], s * r[0] + c * r[1]])
        t = float(plots.times[k])
        if kf is None:
            kf = KalmanFilter(dim_x=4, dim_z=2)
            kf.x = np.array([z[0], 0.0, z[1], 0.0])
            kf.P = np.diag([sigma**2, 100.0, sigma**2, 100.0])
            kf.H = np.array([[1.0, 0, 0, 0], [0, 0, 1.0, 0]])
            kf.R = np.eye(2) * sigma**2
            last = t
            continue
        dt = t - last
        last = t
        kf.F = np.array([[1.0, dt, 0, 0], [0, 1, 0, 0], [0, 0, 1, dt], [0, 0, 0, 1]])
        q1 = np.array([[dt**3 / 3, dt**2 / 2], [dt**2 / 2, dt]])
        kf.Q = np.kron(np.eye(2), q * q1)
        kf.predict()
        kf.update(z)
        total += float(kf.log_likelihood)
    return total


@pytest.fixture(scope="module")
def rec():
    return load_joyride(JOYRIDE)


def test_the_plot_errors_are_a_bearing_bias_about_the_own_ship(rec):
    scans, errs = target_plot_errors(rec)
    terms = error_terms(rec, scans)
    _, raw = fit_errors(errs, [])
    (turn,), left = fit_errors(errs, [terms["turn about own ship"]])
    assert len(scans) > 180 and raw > 20.0  # measured 192 plots, 20.96 m RMS
    assert -2.2 < np.degrees(turn) < -1.5  # measured -1.85 degrees
    # The calibration's exact least-squares rotation (usvfast.radar.bearing_bias_deg) agrees
    # with this small-angle linear fit (measured -1.8497 against -1.8527 degrees).
    assert abs(bearing_bias_deg(rec) - np.degrees(turn)) < 0.005
    assert left < 16.5  # measured 15.90 m: a quarter of the error is the bias
    # The same bias in both halves (measured -2.02 and -1.60 degrees).
    for lo, hi in ((0, HALF), (HALF, rec.n_scans)):
        assert -2.3 < bearing_bias_deg(rec, lo, hi) < -1.3
    # Nothing else explains the error: a turn about the plane's origin, a fixed north/east
    # offset, an antenna offset on the boat or a time lag leave > 18.5 m alone, and add
    # < 0.1 m to the turn about the own ship (its time lag is < 0.1 s).
    for names in (
        ["turn about origin"],
        ["north offset", "east offset"],
        ["along target", "across target"],
        ["time lag"],
    ):
        assert fit_errors(errs, [terms[n] for n in names])[1] > 18.5
        _, both = fit_errors(errs, [terms["turn about own ship"], *(terms[n] for n in names)])
        assert left - both < 0.1
    lag = fit_errors(errs, [terms["turn about own ship"], terms["time lag"]])[0][1]
    assert abs(lag) < 0.1


def test_the_bias_cannot_be_seen_from_the_plots_alone(rec):
    # The plots the tracker follows, turned by 0 or by the bias: equally likely under a
    # constant-velocity filter (a turned track is as smooth as the true one), so no online
    # tracker can estimate the bias - it must come from a calibration.
    plots = read_plots(JOYRIDE)
    res, _ = run_tracking(plots, load_config("joyride"))
    target = track_plots(plots, res)
    assert len(target) > 180
    ll = [plots_log_likelihood(plots, target, d) for d in (-3.0, 0.0, 1.85, 6.0)]
    assert max(ll) - min(ll) < 2.0  # measured 0.8 over 9 degrees, of -1,733
    # A stiffer motion model (q = 0.05, the own ship's turns then show) does prefer a turn, but
    # the largest one offered, driven by the boat's manoeuvres and not the bias; and it fits
    # the plots far worse than q = 1 (log-likelihood -2,425 against -1,732).
    grid = (-6.0, -3.0, 0.0, 1.85, 3.0, 6.0, 10.0)
    stiff = [plots_log_likelihood(plots, target, d, q=0.05) for d in grid]
    assert grid[int(np.argmax(stiff))] == 10.0
    assert max(stiff) < max(ll) - 500
    # ...while against the truth the turn matters: the plots' RMS error falls by 5 m.
    scans, errs = target_plot_errors(rec)
    assert (
        fit_errors(errs, [])[1]
        - fit_errors(errs, [error_terms(rec, scans)["turn about own ship"]])[1]
        > 4.5
    )


def _parts(plots, cfg) -> list:
    res, _ = run_tracking(plots, cfg)
    out = []
    for lo, hi in ((0, len(plots.times)), (0, HALF), (HALF, len(plots.times))):
        sel = (res.scan >= lo) & (res.scan < hi)
        out.append(
            track_quality(
                plots.truth[lo:hi], res.scan[sel] - lo, res.track_id[sel], res.state[sel][:, [0, 2]]
            )
        )
    return out


def test_the_calibrated_preset_meets_the_aims_on_the_held_out_second_half(rec):
    # `joyride-calibrated`: `joyride` + the bias measured on the first half only. Measured on
    # the held-out second half 18.57 m / 98.3 % / 1 / 2 (uncalibrated, the same preset gives
    # 17.61 m / 96.6 % / 1 / 2 there: see the next test); whole recording (half in-sample)
    # 18.08 m / 98.3 % / 1 / 2.
    cfg = load_config("joyride-calibrated")
    assert cfg["bearing_correction_deg"] == pytest.approx(-bearing_bias_deg(rec, 0, HALF), abs=0.01)
    assert {k: v for k, v in cfg.items() if k != "bearing_correction_deg"} == load_config("joyride")
    whole, _, held = _parts(read_plots(JOYRIDE), cfg)
    for q in (held, whole):
        assert q.rmse <= 20.5 and q.coverage >= 0.98
        assert q.fragments == 1 and q.tracks_elsewhere <= 2
    assert held.rmse < 18.7 and whole.rmse < 18.2


@pytest.mark.parametrize("preset", ["joyride", "joyride-known-turns"])
def test_a_calibrated_radar_meets_the_aims_on_the_held_out_half(rec, preset):
    # Diagnostic: the bias measured against the GNSS truth on one half (-2.02 / -1.60 degrees),
    # removed from all plots (bearing_correction_deg), and the unchanged preset scored on the
    # other half. Measured (held-out first half, then second half; uncalibrated in brackets):
    # joyride 17.88 m / 98.3 % / 1 / 0 (22.91 / 96.6) and 18.58 / 98.3 / 1 / 2 (17.61 / 96.6);
    # joyride-known-turns 17.78 / 97.5 / 1 / 0 (22.77 / 95.8) and 16.97 / 97.5 / 1 / 2
    # (18.74 / 96.6). Every aim is met on both held-out halves, and calibrating takes 5 m off
    # the first half's RMSE; on the second half it takes 1.8 m off the known-turn preset's but
    # adds 1.0 m to `joyride`'s, whose settings were tuned on the uncalibrated plots of the
    # whole recording (its uncalibrated second-half figure is in-sample).
    plots = read_plots(JOYRIDE)
    cfg = load_config(preset)
    raw = _parts(plots, cfg)
    for lo, hi, held in ((0, HALF, 2), (HALF, rec.n_scans, 1)):
        cal = _parts(plots, cfg | {"bearing_correction_deg": -bearing_bias_deg(rec, lo, hi)})
        q = cal[held]
        assert q.rmse <= 20.5 and q.coverage >= 0.97
        assert q.fragments == 1 and q.tracks_elsewhere <= 2
        if preset == "joyride" and held == 2:
            assert raw[held].rmse + 0.5 < q.rmse < raw[held].rmse + 1.5
        else:
            assert q.rmse < raw[held].rmse - 1.5
