"""Radar plot readers: NMEA ARPA sentences TTM/TLL (pynmea2, checksums, units, relative
bearings, times from tag blocks / leading columns / the ZDA clock with midnight rollover),
CSV plots, and the bad input the issue names (unknown radar sentence, plots out of time
order) counted and skipped; polar plots placed in NED from the own ship."""

from __future__ import annotations

import calendar
import datetime as dt
from functools import reduce
from operator import xor

import numpy as np
import pytest

from usvfast import geodesy
from usvfast._damage import DamagedRecordsWarning
from usvfast.fusion import OwnShip, run_vts
from usvfast.fusion.pipeline import _plots_ned
from usvfast.radar import LogClock, plots_from_ned, read_radar_csv, read_radar_nmea


def nmea(body: str) -> str:
    return f"${body}*{reduce(xor, body.encode(), 0):02X}"


def ttm(num, dist_nm, brg, tod, ref="T", status="T", unit="N", speed="10.0"):
    return nmea(
        f"RATTM,{num:02d},{dist_nm},{brg},{ref},{speed},90.0,T,0.2,5.0,{unit},TGT,{status},,{tod},A"
    )


DAY = calendar.timegm((2016, 12, 31, 0, 0, 0))


def test_ttm_tll_with_zda_clock_units_and_midnight_rollover():
    lines = [
        nmea("GPZDA,235958.00,31,12,2016,00,00"),
        ttm(1, "0.50", "45.0", "235959.00"),
        ttm(2, "1.50", "145.0", "000001.00", unit="K", speed="36.0"),
        nmea("RATLL,03,6325.1234,N,01023.4567,E,TGT3,000002.00,T,"),
        ttm(4, "0.20", "10.0", "000003.00", status="L"),  # lost target: skipped
    ]
    p = read_radar_nmea(lines)
    np.testing.assert_allclose(p.time, [DAY + 86399.0, DAY + 86401.0, DAY + 86402.0])
    np.testing.assert_allclose(p.range_m[:2], [926.0, 1500.0])
    np.testing.assert_allclose(p.bearing_deg[:2], [45.0, 145.0])
    np.testing.assert_allclose(p.speed[:2], [10.0 * 1852 / 3600, 10.0])
    assert p.target_number.tolist() == [1, 2, 3]
    assert p.lat_deg[2] == pytest.approx(63 + 25.1234 / 60) and np.isnan(p.range_m[2])
    assert p.lon_deg[2] == pytest.approx(10 + 23.4567 / 60)
    assert (p.n_read, p.n_damaged, p.n_unknown, p.n_ignored) == (4, 0, 0, 1)


def test_tag_block_and_leading_time_win_over_the_time_of_day():
    tag = "c:1495196206"
    lines = [
        f"\\{tag}*{reduce(xor, tag.encode(), 0):02X}\\" + ttm(1, "0.5", "0", "120000.00"),
        "1495196208.5 " + ttm(1, "0.5", "1", "120002.00"),
    ]
    p = read_radar_nmea(lines)
    np.testing.assert_allclose(p.time, [1495196206.0, 1495196208.5])
    # A time of day without any date is an error per line, and no line left is an error.
    with pytest.warns(DamagedRecordsWarning), pytest.raises(ValueError, match="no usable"):
        read_radar_nmea([ttm(1, "0.5", "0", "120000.00")])
    p = read_radar_nmea([ttm(1, "0.5", "0", "120000.00")], date=dt.date(2017, 5, 19))
    assert p.time[0] == calendar.timegm((2017, 5, 19, 12, 0, 0))


def test_damaged_unknown_and_out_of_order_are_counted_and_skipped():
    lines = [
        nmea("GPZDA,120000.00,19,05,2017,00,00"),
        ttm(1, "0.5", "10", "120001.00"),
        ttm(1, "0.5", "10", "120003.00")[:-2] + "00",  # bad checksum
        nmea("RAXYZ,1,2,3"),  # an unknown radar sentence
        ttm(2, "0.6", "20", "120000.00"),  # out of time order
        nmea("RATTM,03,,10,T,,,,,,N,,T,,120004.00,A"),  # no distance
        "garbage",
        ttm(3, "0.7", "30", "120005.00"),
    ]
    with pytest.warns(DamagedRecordsWarning, match="unknown radar sentence"):
        p = read_radar_nmea(lines)
    assert p.target_number.tolist() == [1, 3]
    assert p.n_unknown == 1
    assert p.n_damaged == 3  # checksum, time order, missing distance
    assert p.n_ignored == 2  # ZDA and garbage


def test_csv_polar_and_ned(tmp_path):
    f = tmp_path / "plots.csv"
    f.write_text(
        "time,range,bearing,target\n10,100,90,1\n10,200,0,\n9,50,0,\n11,x,0,\n12,300,370,2\n"
    )
    with pytest.warns(DamagedRecordsWarning, match="2 radar plot"):
        p = read_radar_csv(f)
    np.testing.assert_allclose(p.time, [10, 10, 12])
    np.testing.assert_allclose(p.bearing_deg, [90, 0, 10])
    assert p.target_number.tolist() == [1, -1, 2]
    times, index = p.scans()
    assert times.tolist() == [10.0, 12.0] and index.tolist() == [0, 0, 1]
    g = tmp_path / "ned.csv"
    g.write_text("time,north,east\n1,5,6\n")
    q = read_radar_csv(g)
    assert (q.north[0], q.east[0]) == (5.0, 6.0) and np.isnan(q.range_m[0])
    bad = tmp_path / "bad.csv"
    bad.write_text("t,r\n1,2\n")
    with pytest.raises(ValueError, match="header"):
        read_radar_csv(bad)


def test_polar_plots_are_placed_from_the_own_ship():
    origin = (63.0, 10.0)
    own = OwnShip(
        np.array([0.0, 10.0]), np.array([0.0, 100.0]), np.array([0.0, 0.0]), np.array([0.0, 90.0])
    )
    lines = [
        "5 " + ttm(1, f"{1000 / 1852:.6f}", "90.0", "000005.00"),  # true bearing east
        "5 " + ttm(2, f"{1000 / 1852:.6f}", "0.0", "000005.00", ref="R"),  # ahead: heading 45
        "6 " + nmea("RATLL,03,6300.5400,N,01000.0000,E,X,000006.00,T,"),
    ]
    p = read_radar_nmea(lines)
    xy, brg = _plots_ned(p, own, origin)
    np.testing.assert_allclose(brg[:2], [90.0, 45.0])
    assert np.isnan(brg[2])
    np.testing.assert_allclose(xy[0], [50.0, 1000.0], atol=1e-3)
    np.testing.assert_allclose(xy[1], [50 + 1000 / np.sqrt(2), 1000 / np.sqrt(2)], atol=0.5)
    n, e, _ = geodesy.geodetic2ned(63.009, 10.0, 0.0, *origin, 0.0)
    np.testing.assert_allclose(xy[2], [n, e], atol=1e-6)
    with pytest.raises(ValueError, match="own"):
        _plots_ned(p, None, origin)


def test_clock_and_ned_plots():
    c = LogClock()
    assert np.isnan(c.time_of(b"!AIVDM,1,1,,A,x,0*00"))
    c.time_of(nmea("GPRMC,130711.00,A,5012.79,N,00806.87,W,0.5,3.0,010611,,A").encode())
    assert c.time_of(b"!AIVDM") == calendar.timegm((2011, 6, 1, 13, 7, 11)) and c.n_clock == 1
    p = plots_from_ned([1.0, 2.0], [np.array([[1.0, 2.0], [3.0, 4.0]]), np.zeros((0, 2))])
    assert p.north.tolist() == [1.0, 3.0] and p.time.tolist() == [1.0, 1.0]


def test_run_vts_without_ais_tracks_radar_only():
    rng = np.random.default_rng(0)
    times = np.arange(0.0, 100.0, 2.5)
    scans = [np.array([[100 + 5 * t, 50.0]]) + rng.normal(0, 5, (1, 2)) for t in times]
    res = run_vts(plots_from_ned(times, scans), None, None, origin=(60.0, 5.0))
    assert {r.source for r in res.rows} == {"radar"}
    assert len({r.track_id for r in res.rows}) == 1


def test_polar_plot_covariance_is_the_converted_measurement_covariance():
    from usvfast.fusion import TrackerConfig
    from usvfast.fusion.pipeline import _plot_covariances

    rng = np.random.default_rng(4)
    r0, b0 = 1500.0, 35.0
    cfg = TrackerConfig(range_std=10.0, bearing_std_deg=1.0, sigma=25.0)
    lines = [
        "5 " + ttm(1, f"{r0 / 1852:.7f}", f"{b0}", "000005.00"),
        "6 " + nmea("RATLL,03,6300.5400,N,01000.0000,E,X,000006.00,T,"),
    ]
    p = read_radar_nmea(lines)
    cov = _plot_covariances(p, np.array([b0, np.nan]), cfg)
    r = r0 + 10.0 * rng.standard_normal(200000)
    b = np.radians(b0 + 1.0 * rng.standard_normal(200000))
    mc = np.cov(np.stack([r * np.cos(b), r * np.sin(b)]))
    np.testing.assert_allclose(cov[0], mc + np.eye(2), rtol=0.02)
    np.testing.assert_allclose(cov[1], 625.0 * np.eye(2))


def test_identity_survives_a_track_break_within_t_d_and_radius():
    from usvfast.fusion import TrackerConfig

    rng = np.random.default_rng(1)
    times = np.arange(0.0, 140.0, 2.5)
    # The target is not seen from 60 s to 80 s (scans with scattered clutter only).
    scans = [
        np.array([[100 + 5 * t, 50.0]]) + rng.normal(0, 3, (1, 2))
        if not 60 <= t < 80
        else rng.uniform(2000, 9000, (1, 2))
        for t in times
    ]
    plots = plots_from_ned(times, scans)
    cfg = TrackerConfig(delete_steps=3, sigma=5.0)
    kept = run_vts(plots, None, None, origin=(60.0, 5.0), tracker=cfg, t_d=30.0, radius=60.0)
    split = run_vts(plots, None, None, origin=(60.0, 5.0), tracker=cfg, t_d=30.0, radius=1.0)

    def target_ids(res):
        return {r.track_id for r in res.rows if r.north < 1000 and abs(r.east - 50) < 30}

    assert len(target_ids(split)) == 2  # the tracker itself starts a new track after the gap
    assert len(target_ids(kept)) == 1  # §1.2: the same object keeps its identity


@pytest.mark.parametrize("mode", ["ekf", "ukf", "converted"])
def test_polar_plots_tracked_with_the_range_bearing_sensor(tmp_path, mode):
    from usvfast.fusion import TrackerConfig

    rng = np.random.default_rng(3)
    times = np.arange(0.0, 300.0, 2.5)
    own_n, own_e = 3.0 * times, np.zeros(len(times))  # own ship steaming north at 3 m/s
    truth = np.stack([1500.0 + 0 * times, -800.0 + 5.0 * times], axis=1)  # crossing east
    rel = truth - np.stack([own_n, own_e], axis=1)
    rng_m = np.hypot(rel[:, 0], rel[:, 1]) + rng.normal(0, 10.0, len(times))
    brg = np.degrees(np.arctan2(rel[:, 1], rel[:, 0])) + rng.normal(0, 1.0, len(times))
    f = tmp_path / "plots.csv"
    f.write_text(
        "time,range,bearing\n"
        + "".join(f"{t},{r},{b % 360}\n" for t, r, b in zip(times, rng_m, brg, strict=True))
    )
    own = OwnShip(times, own_n, own_e, np.zeros(len(times)))
    cfg = TrackerConfig(q=0.5, sigma=25.0, polar=mode)
    res = run_vts(read_radar_csv(f), None, own, origin=(60.0, 5.0), tracker=cfg)
    ids = {r.track_id for r in res.rows}
    assert len(ids) == 1
    pos = {r.time: (r.north, r.east) for r in res.rows}
    err = [
        np.hypot(*(np.array(pos[t]) - x))
        for t, x in zip(times, truth, strict=True)
        if t in pos and t > 60
    ]
    rmse = float(np.sqrt(np.mean(np.square(err))))
    # 1 deg at ~1.7 km is ~30 m across the line of sight; the track smooths it.
    assert rmse < 20.0, (mode, rmse)
    print(f"{mode}: RMSE {rmse:.2f} m")
