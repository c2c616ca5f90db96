"""AIS reader against GPSD's decoding of real traffic (sample.aivdm.js.chk), damaged and
incomplete sentences, and dead reckoning against pymap3d's exact geodesy."""

from __future__ import annotations

import json
import math

import numpy as np
import pymap3d
import pytest

from usvfast import NonFiniteError
from usvfast.nav.ais import AisPositions, dead_reckon, read_ais
from usvfast.nav.nmea import KNOT, DamagedRecordsWarning

from conftest import SHARED_DATA

DATA = SHARED_DATA / "nmea"


def gpsd():
    lines = (DATA / "sample.aivdm.js.chk").read_text().splitlines()
    return [json.loads(ln) for ln in lines if ln.startswith("{")]


def test_position_reports_equal_gpsd():
    log = read_ais(DATA / "sample.aivdm")
    assert log.n_damaged == 0 and log.n_incomplete == 0
    ref = [r for r in gpsd() if r["type"] in (1, 2, 3, 18, 19, 27)]
    p = log.positions
    assert len(ref) == len(p.mmsi) == 12
    for k, r in enumerate(ref):
        assert p.mmsi[k] == r["mmsi"] and p.msg_type[k] == r["type"]
        # Type 27 has 1/10-minute resolution and GPSD prints it with one decimal.
        tol = 0.05 if r["type"] == 27 else 1e-6
        assert p.lat_deg[k] == pytest.approx(r["lat"], abs=tol)
        assert p.lon_deg[k] == pytest.approx(r["lon"], abs=tol)
        assert p.speed[k] / KNOT == pytest.approx(r["speed"], abs=1e-6)
        assert p.course_deg[k] == pytest.approx(r["course"], abs=1e-6)
        if r.get("heading", 511) == 511:
            assert math.isnan(p.heading_deg[k])
        else:
            assert p.heading_deg[k] == r["heading"]
    assert not p.own_ship.any() and np.isnan(p.time).all()


def test_static_data_equals_gpsd():
    log = read_ais(DATA / "sample.aivdm")
    checked = 0
    for r in gpsd():
        if r["type"] in (5, 19, 24) and "to_bow" in r:
            s = log.static[r["mmsi"]]
            assert s.name == r["shipname"].strip()
            assert (s.to_bow, s.to_stern, s.to_port, s.to_starboard) == (
                r["to_bow"],
                r["to_stern"],
                r["to_port"],
                r["to_starboard"],
            )
            assert s.length == r["to_bow"] + r["to_stern"]
            assert s.ship_type == r["shiptype"]
            checked += 1
    assert checked >= 6
    assert log.static[351759000].name == "EVER DIADEM"  # a two-fragment type 5


def test_own_ship_and_mixed_log():
    log = read_ais(DATA / "saab-r4.log")
    p = log.positions
    assert log.n_sentences == 14 and log.n_ignored == 108  # the NMEA lines around them
    assert p.own_ship.sum() == 12 and set(p.mmsi[p.own_ship]) == {244121341}
    assert set(p.mmsi[~p.own_ship]) == {244707571}


def test_damaged_and_incomplete_are_skipped_and_counted():
    lines = (DATA / "sample.aivdm").read_text().splitlines()
    ais = [ln for ln in lines if ln.startswith("!")]
    first_of_two = next(i for i, ln in enumerate(ais) if ln.startswith("!AIVDM,2,1"))
    bad = list(ais)
    del bad[first_of_two + 1]  # its second fragment is lost
    bad.insert(0, ais[0][:-2] + ("00" if not ais[0].endswith("00") else "11"))  # checksum
    bad.insert(3, "!AIVDM,1,1,,A,\x01\x02garbage,0*00")
    bad.insert(5, "$GPHDT,12.5,T*00")  # not AIS
    with pytest.warns(DamagedRecordsWarning):
        log = read_ais(bad)
    clean = read_ais([ln for i, ln in enumerate(ais) if i not in (first_of_two, first_of_two + 1)])
    assert log.n_damaged == 2 and log.n_incomplete == 1 and log.n_ignored == 1
    assert log.n_messages == clean.n_messages
    np.testing.assert_array_equal(log.positions.mmsi, clean.positions.mmsi)
    with pytest.raises(ValueError, match="no decodable"):
        read_ais(["!AIVDM,1,1,,A,zzz,0*00"])


def report(**kw):
    base = dict(
        time=[0.0], mmsi=[7], msg_type=[1], own_ship=[False], lat_deg=[59.0],
        lon_deg=[10.0], speed=[10.0], course_deg=[90.0], heading_deg=[88.0], second=[0],
        status=[0],
    )  # fmt: skip
    base.update(kw)
    return AisPositions(**{k: np.asarray(v) for k, v in base.items()})


def test_dead_reckoning_against_pymap3d():
    pos = report(
        time=[0.0, 100.0], mmsi=[7, 7], msg_type=[1, 1], own_ship=[False, False],
        lat_deg=[59.0, 59.01], lon_deg=[10.0, 10.02], speed=[10.0, 4.0],
        course_deg=[90.0, 225.0], heading_deg=[88.0, 230.0], second=[0, 40], status=[0, 0],
    )  # fmt: skip
    t = np.array([-5.0, 0.0, 50.0, 100.0, 130.0])
    lat, lon, age = dead_reckon(pos, 7, t, max_age=60.0)
    np.testing.assert_array_equal(np.isnan(lat), [True, False, False, False, False])
    np.testing.assert_allclose(age[1:], [0.0, 50.0, 0.0, 30.0])
    elat, elon, _ = pymap3d.ned2geodetic(0.0, 500.0, 0.0, 59.0, 10.0, 0.0)
    assert lat[2] == pytest.approx(elat, abs=1e-9) and lon[2] == pytest.approx(elon, abs=1e-9)
    d = 4.0 * 30.0 / math.sqrt(2.0)
    elat, elon, _ = pymap3d.ned2geodetic(-d, -d, 0.0, 59.01, 10.02, 0.0)
    assert lat[4] == pytest.approx(elat, abs=1e-9) and lon[4] == pytest.approx(elon, abs=1e-9)
    lat, _, age = dead_reckon(pos, 7, 170.0, max_age=60.0)
    assert np.isnan(lat) and age == 70.0
    with pytest.raises(ValueError, match="mmsi"):
        dead_reckon(pos, 8, [1.0])


def test_dead_reckoning_without_course_or_speed_is_stationary():
    # A report with a speed but no course used to move the target north.
    for speed, course in [(10.0, np.nan), (np.nan, 90.0), (np.nan, np.nan)]:
        pos = report(speed=[speed], course_deg=[course])
        lat, lon, age = dead_reckon(pos, 7, [0.0, 60.0])
        np.testing.assert_allclose(lat, [59.0, 59.0], rtol=0, atol=1e-12)
        np.testing.assert_allclose(lon, [10.0, 10.0], rtol=0, atol=1e-12)
        np.testing.assert_array_equal(age, [0.0, 60.0])


def test_dead_reckoning_skips_reports_without_longitude():
    pos = report(
        time=[0.0, 100.0], mmsi=[7, 7], msg_type=[1, 1], own_ship=[False, False],
        lat_deg=[59.0, 59.5], lon_deg=[10.0, np.nan], speed=[0.0, 0.0],
        course_deg=[0.0, 0.0], heading_deg=[0.0, 0.0], second=[0, 40], status=[0, 0],
    )  # fmt: skip
    lat, lon, age = dead_reckon(pos, 7, [150.0])
    np.testing.assert_allclose(lat, [59.0], rtol=0, atol=1e-12)
    np.testing.assert_allclose(lon, [10.0], rtol=0, atol=1e-12)
    np.testing.assert_array_equal(age, [150.0])
    with pytest.raises(ValueError, match="mmsi"):
        dead_reckon(report(lon_deg=[np.nan]), 7, [1.0])


def test_dead_reckoning_checks_times():
    with pytest.raises(NonFiniteError, match="times"):
        dead_reckon(report(), 7, [0.0, np.nan])
    with pytest.raises(TypeError, match="times"):
        dead_reckon(report(), 7, ["soon"])
