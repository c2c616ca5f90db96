"""AIS feeds with receive times (tag blocks, leading columns, the log's ZDA clock on the real
Saab R4 capture), AIS targets in NED with the report-age covariance (filterpy's continuous
white-noise Q as the oracle), fix times from the `second` field, and bad input: AIS without
positions, feeds without any time."""

from __future__ import annotations

import calendar
from functools import reduce
from operator import xor

import aisgen as G
import numpy as np
import pytest
from pyais import encode_dict

from usvfast import geodesy
from usvfast.fusion import AisTargets, read_ais_feed
from usvfast.fusion.ais_feed import fix_times
from usvfast.nav.ais import dead_reckon

from conftest import SHARED_DATA

NMEA = SHARED_DATA / "nmea"


def _tag(body: str) -> str:
    return f"\\{body}*{reduce(xor, body.encode(), 0):02X}\\"


def _report(mmsi=257000009, lat=63.0, lon=10.0, speed=10.0, course=90.0, second=30):
    d = dict(type=1, msg_type=1, mmsi=mmsi, lat=lat, lon=lon, speed=speed, course=course)
    d["second"] = second
    return encode_dict(d, talker_id="AI", sentence_type="VDM")[0]


def test_saab_log_gets_times_from_its_zda_clock():
    feed = read_ais_feed(NMEA / "saab-r4.log")
    p = feed.log.positions
    # The first AIVDM and AIVDO come before the first ZDA: the reader times them from that
    # first clock and their own UTC-second field, so none is left untimed.
    assert feed.n_untimed == 0 and feed.n_clock > 10
    t = p.time[np.isfinite(p.time)]
    assert t.min() >= calendar.timegm((2011, 6, 1, 13, 7, 11))
    assert t.max() <= calendar.timegm((2011, 6, 1, 13, 8, 0))
    targets = AisTargets(feed, (50.2, -8.1))
    assert targets.mmsis.tolist() == [244707571]  # the own ship (!AIVDO) is left out


def test_tag_block_leading_column_multi_sentence_and_bad_tag():
    static = encode_dict(
        dict(type=5, msg_type=5, mmsi=257000009, shipname="TESTBOAT", callsign="LA1"),
        talker_id="AI",
        sentence_type="VDM",
        seq_id=3,
    )
    assert len(static) == 2
    lines = [_tag("c:1700000000") + part for part in static]
    lines.append(_tag("c:1700000010") + _report(second=9))
    lines.append("1700000020.5 " + _report(second=20))
    lines.append("\\c:1700000030*00\\" + _report(second=30))  # wrong tag checksum
    feed = read_ais_feed(lines)
    assert feed.names == {257000009: "TESTBOAT"}
    assert feed.n_bad_tag == 1
    np.testing.assert_allclose(feed.log.positions.time, [1700000010.0, 1700000020.5])
    # Timed by the fix: the latest whole second with the report's UTC second.
    np.testing.assert_allclose(fix_times(feed.log.positions).time, [1700000009.0, 1700000020.0])


def test_ais_targets_dead_reckon_and_covariance_matches_filterpy():
    from filterpy.common import Q_continuous_white_noise

    lines = [_tag("c:1700000000") + _report(lat=63.0, lon=10.0, speed=10.0, course=90.0, second=20)]
    origin = (63.0, 10.0)
    t = AisTargets(read_ais_feed(lines), origin, pos_std=5.0, vel_std=0.3, accel_psd=0.5)
    st = t.states_at(1700000030.0)
    lat, lon, age = dead_reckon(t.positions, 257000009, [1700000030.0])
    n, e, _ = geodesy.geodetic2ned(lat, lon, 0.0, *origin, 0.0)
    np.testing.assert_allclose(st.state[0], [n[0], 0.0, e[0], 10.0 * 1852 / 3600], atol=1e-6)
    assert st.state[0, 2] == pytest.approx(30 * 10 * 1852 / 3600, rel=1e-3)
    a = 30.0
    f = np.array([[1.0, a], [0.0, 1.0]])
    ref = f @ np.diag([25.0, 0.09]) @ f.T + Q_continuous_white_noise(2, dt=a, spectral_density=0.5)
    np.testing.assert_allclose(st.cov[0][:2, :2], ref, rtol=1e-12)
    np.testing.assert_allclose(st.cov[0][2:, 2:], ref, rtol=1e-12)
    assert age[0] == st.age[0] == 30.0
    assert len(t.states_at(1700000000.0 + 121.0).mmsi) == 0  # beyond max_age
    assert len(t.states_at(1699999999.0).mmsi) == 0  # before the first report
    with pytest.raises(ValueError, match="pos_std"):
        AisTargets(read_ais_feed(lines), origin, pos_std=0.0)


def test_ais_without_positions_or_times_is_a_clear_error():
    rng = np.random.default_rng(0)
    v = G.straight(257000010, "NOPOS", 1700000000.0, 1700000100.0, (0.0, 0.0), (3.0, 0.0))
    lines = [line for _, line in G.ais_lines(v, (60.0, 5.0), rng, position=False)]
    with pytest.raises(
        ValueError, match="no AIS position report with a receive time and a position"
    ):
        read_ais_feed(lines)
    # GPSD's sample.aivdm carries no receive time at all.
    with pytest.raises(ValueError, match="receive time"):
        read_ais_feed(NMEA / "sample.aivdm")


def test_itu_intervals():
    assert G.itu_interval(10.0, 0.0) == 10.0
    assert G.itu_interval(10.0, 20.0) == pytest.approx(10 / 3)
    assert G.itu_interval(18.0, 0.0) == 6.0 and G.itu_interval(18.0, 20.0) == 2.0
    assert G.itu_interval(25.0, 0.0) == 2.0
