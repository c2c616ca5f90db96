"""NMEA reader against GPSD's independent decoding of real receiver logs, synthetic midnight
rollovers built with pynmea2, and mangled copies (valid records are never lost)."""

from __future__ import annotations

import datetime as dt
import json
import random
import warnings

import numpy as np
import pynmea2
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from usvfast.nav.nmea import DamagedRecordsWarning, compass_heading, read_nmea
from usvfast.pipeline.live_pose import parse_sentence

from conftest import SHARED_DATA

DATA = SHARED_DATA / "nmea"
LOGS = ["ublox-zed-f9p-nmea.log", "saab-r4.log", "sirfstarv-nmea.log"]


def gpsd_reports(name, cls):
    out = []
    for line in (DATA / f"{name}.chk").read_text().splitlines():
        if line.startswith("{"):
            rec = json.loads(line)
            if rec.get("class") == cls:
                out.append(rec)
    return out


def tod(iso):
    """Seconds of day of a GPSD ISO time (its year can be wrong: GPS week rollover)."""
    t = dt.datetime.fromisoformat(iso.replace("Z", "+00:00"))
    return t.hour * 3600 + t.minute * 60 + t.second + t.microsecond * 1e-6


@pytest.mark.parametrize("name", LOGS)
def test_positions_equal_gpsd(name):
    log = read_nmea(DATA / name)
    assert log.n_damaged == 0 and log.n_used > 0
    p = log.positions
    assert np.all(np.diff(p.time) > 0)
    ours = {
        round(t % 86400, 3): (la, lo)
        for t, la, lo in zip(p.time, p.lat_deg, p.lon_deg, strict=True)
    }
    matched = 0
    for rec in gpsd_reports(name, "TPV"):
        if "lat" in rec and "time" in rec:
            la, lo = ours[round(tod(rec["time"]), 3)]
            assert la == pytest.approx(rec["lat"], abs=1e-8)
            assert lo == pytest.approx(rec["lon"], abs=1e-8)
            matched += 1
    assert matched >= len(p.time)


@pytest.mark.parametrize("name", ["ublox-zed-f9p-nmea.log", "sirfstarv-nmea.log"])
def test_dates_and_speeds_equal_gpsd(name):
    # These receivers' dates are right in GPSD's output: compare absolute times too.
    log = read_nmea(DATA / name)
    gps_times = {
        dt.datetime.fromisoformat(r["time"].replace("Z", "+00:00")).timestamp()
        for r in gpsd_reports(name, "TPV")
        if "time" in r
    }
    assert set(log.positions.time) <= gps_times
    v = log.velocities
    rmc = {
        t: (s, c)
        for t, s, c, k in zip(v.time, v.speed, v.course_deg, v.sentence, strict=True)
        if k == "RMC"
    }
    checked = 0
    for rec in gpsd_reports(name, "TPV"):
        t = dt.datetime.fromisoformat(
            rec.get("time", "1970-01-01T00:00:00Z").replace("Z", "+00:00")
        )
        if "speed" in rec and t.timestamp() in rmc:
            speed, course = rmc[t.timestamp()]
            assert speed == pytest.approx(rec["speed"], abs=1e-3)
            if "track" in rec:
                assert course == pytest.approx(rec["track"], abs=1e-4)
            checked += 1
    assert checked > 20


def test_saab_heading_rot_and_date():
    log = read_nmea(DATA / "saab-r4.log")
    # ZDA/RMC say 2011-06-01 (GPSD's .chk year is wrong there, see the data README).
    first = dt.datetime.fromtimestamp(log.positions.time[0], dt.timezone.utc)
    assert first == dt.datetime(2011, 6, 1, 13, 7, 11, tzinfo=dt.timezone.utc)
    h = log.headings
    assert len(h.time) == 12 and set(h.talker) == {"HE"} and set(h.sentence) == {"HDT"}
    # Own-ship AIS (!AIVDO) heading decoded by GPSD, same second, equals the gyro's HDT.
    own = {
        r["second"]: r["heading"]
        for r in gpsd_reports("saab-r4.log", "AIS")
        if r["mmsi"] == 244121341
    }
    compared = 0
    for t, hd in zip(h.time, h.heading_deg, strict=True):
        if int(t) % 60 in own:
            assert round(hd) == own[int(t) % 60]
            compared += 1
    assert compared >= 10
    assert len(log.rates_of_turn.time) == 12 and np.all(log.rates_of_turn.valid)
    # GGA quality 2 (DGPS) in this log.
    assert set(log.positions.fix_quality) == {2}


def gga(time, quality="1", talker="GP", lat="5000.0", ns="N", lon="00100.0", ew="E"):
    fields = [time, lat, ns, lon, ew, quality, "08", "0.9", "10.0", "M", "", "", "", ""]
    return str(pynmea2.GGA(talker, "GGA", fields))


def rmc(time, date):
    fields = [time, "A", "5000.0", "N", "00100.0", "E", "1.0", "90.0", date, "", "", "A"]
    return str(pynmea2.RMC("GN", "RMC", fields))


def hdt(heading, talker="HE"):
    return str(pynmea2.HDT(talker, "HDT", [heading, "T"]))


def test_midnight_rollover_and_backfill():
    lines = [
        gga("235958"),  # before any date: resolved backwards from the first RMC
        hdt("12.5"),
        rmc("235959.00", "311223"),
        gga("235959.50"),
        gga("000000.50", quality="4"),  # midnight: the time of day wraps before a new date
        hdt("13.0", talker="IN"),
        gga("000001.00", quality="5", talker="GN"),
        str(pynmea2.ZDA("GP", "ZDA", ["000002.00", "01", "01", "2024", "00", "00"])),
        gga("000002.00"),
    ]
    log = read_nmea(lines)
    midnight = dt.datetime(2024, 1, 1, tzinfo=dt.timezone.utc).timestamp()
    np.testing.assert_allclose(log.positions.time - midnight, [-2.0, -1.0, -0.5, 0.5, 1.0, 2.0])
    np.testing.assert_array_equal(log.positions.fix_quality, [1, 1, 1, 4, 5, 1])
    np.testing.assert_array_equal(log.positions.talker, ["GP", "GN", "GP", "GP", "GN", "GP"])
    np.testing.assert_allclose(log.headings.time - midnight, [-2.0, 0.5])
    np.testing.assert_array_equal(log.headings.talker, ["HE", "IN"])
    # The RMC at 23:59:59 shares its time with no GGA: it is the position there.
    assert log.positions.sentence[1] == "RMC"


def test_no_date_needs_a_date_argument():
    lines = [gga("120000", lat="5030.0", ns="S", lon="00130.0", ew="W")]
    with pytest.raises(ValueError, match="date"):
        read_nmea(lines)
    log = read_nmea(lines, date=dt.date(2020, 2, 29))
    noon = dt.datetime(2020, 2, 29, 12, tzinfo=dt.timezone.utc).timestamp()
    assert log.positions.time[0] == noon
    assert log.positions.lat_deg[0] == -50.5 and log.positions.lon_deg[0] == -1.5


def test_nothing_usable_fails_loudly(tmp_path):
    bad = tmp_path / "bad.log"
    bad.write_bytes(b"\xff\xfe garbage\n$GPGGA,1*00\n")
    with pytest.raises(ValueError, match="no usable"):
        read_nmea(bad)


def test_checksum_required_by_default():
    bare = "$GPHDT,12.5,T"
    with pytest.raises(ValueError, match="1 damaged"):
        read_nmea([bare])
    zda = str(pynmea2.ZDA("GP", "ZDA", ["000002.00", "01", "01", "2024", "00", "00"]))
    with pytest.warns(DamagedRecordsWarning, match="1 damaged"):
        log = read_nmea([zda, bare])
    assert log.n_damaged == 1 and len(log.headings.time) == 0
    log = read_nmea([zda, bare], require_checksum=False)
    assert log.n_damaged == 0 and log.headings.heading_deg.tolist() == [12.5]


def sentence(body: str) -> str:
    """`$body*hh` with its checksum."""
    cs = 0
    for c in body.encode():
        cs ^= c
    return f"${body}*{cs:02X}"


def test_gnss_compass_headings_equal_pynmea2():
    hpr = sentence("PSAT,HPR,120000.50,89.58,3.35,,N")  # Hemisphere
    ash = sentence("PASHR,HPR,120001.00,359.99,-1.20,,0.004,0.000,0,0,2.888,1.8")  # Ashtech
    avr = sentence("PTNL,AVR,120001.50,-52.1531,Yaw,-0.0806,Tilt,,,12.575,3,1.4,16")  # Trimble
    no_fix = sentence("PTNL,AVR,120002.00,+10.0,Yaw,,,,,12.575,0,1.4,16")
    empty = sentence("PSAT,HPR,120002.50,,,,N")
    attitude = sentence("PASHR,120003.00,90.0,T,1.0,2.0,,0.1,0.1,0.2,1,0")  # not a heading
    with pytest.warns(DamagedRecordsWarning, match="2 damaged"):
        log = read_nmea([rmc("120000.00", "050126"), hpr, ash, avr, no_fix, empty, attitude])
    noon = dt.datetime(2026, 1, 5, 12, tzinfo=dt.timezone.utc).timestamp()
    np.testing.assert_allclose(log.headings.time - noon, [0.5, 1.0, 1.5])
    expected = [
        float(pynmea2.parse(hpr).data[3]),
        float(pynmea2.parse(ash).heading),
        float(pynmea2.parse(avr).yaw_angle) % 360.0,
    ]
    np.testing.assert_allclose(log.headings.heading_deg, expected, rtol=0, atol=1e-12)
    assert log.headings.heading_deg[2] == pytest.approx(307.8469)
    assert log.headings.sentence.tolist() == ["HPR", "HPR", "AVR"]
    assert log.headings.talker.tolist() == ["SAT", "ASH", "TNL"]
    assert log.n_damaged == 2 and log.n_ignored == 1  # no fix and empty; PASHR attitude
    for line, heading in zip((hpr, ash, avr), expected, strict=True):
        assert parse_sentence(line) == ("heading", (pytest.approx(heading, abs=1e-9),))
    assert parse_sentence(avr[:-2] + "00") is None  # bad checksum
    assert parse_sentence(no_fix) is None
    assert compass_heading("GPHDT,12.5,T") is None
    with pytest.raises(ValueError, match="PTNL,AVR without a valid heading"):
        compass_heading(no_fix[1:-3])


def mangle(line: str, how: int, rng: random.Random) -> bytes:
    if how == 0:  # truncated (never back to a valid sentence: the checksum goes)
        star = line.find("*")
        return line[: rng.randint(1, star - 1)].encode()
    if how == 1:  # bad checksum
        given = int(line[-2:], 16)
        return (line[:-2] + f"{(given + rng.randint(1, 255)) % 256:02X}").encode()
    if how == 2:  # a payload character changed, checksum kept
        i = rng.randint(1, line.find("*") - 1)
        c = "7" if line[i] != "7" else "3"
        return (line[:i] + c + line[i + 1 :]).encode()
    # binary garbage spliced into the line
    i = rng.randint(0, len(line))
    return line[:i].encode() + bytes(rng.randint(128, 255) for _ in range(5)) + line[i:].encode()


@settings(max_examples=25)
@given(st.integers(0, 2**32 - 1), st.floats(0.01, 0.5))
def test_mangled_copies_keep_every_valid_record(tmp_path_factory, seed, fraction):
    rng = random.Random(seed)
    lines = []
    for line in (DATA / "ublox-zed-f9p-nmea.log").read_text().splitlines():
        lines.append(line)
        if line[3:6] == "GGA":  # a GNSS compass's heading at each fix, on the fix's time
            lines.append(sentence(f"PSAT,HPR,{line.split(',')[1]},{rng.uniform(0, 360):.2f},,,N"))
    assert sum(line.startswith("$PSAT,HPR") for line in lines) > 20  # one per GGA
    out, kept = [], []
    n_bad = 0
    for line in lines:
        if line.startswith("$") and rng.random() < fraction:
            out.append(mangle(line, rng.randint(0, 3), rng))
            n_bad += 1
        else:
            out.append(line.encode())
            kept.append(line)
        if rng.random() < 0.02:  # a line of pure binary noise
            out.append(bytes(rng.randint(128, 255) for _ in range(rng.randint(1, 40))))
            n_bad += 1
    path = tmp_path_factory.mktemp("m") / "mangled.log"
    path.write_bytes(b"\n".join(out) + b"\n")
    with warnings.catch_warnings():  # it may drop a leading time-less VTG too, and say so
        warnings.simplefilter("ignore", DamagedRecordsWarning)
        clean = read_nmea(kept)  # the oracle: the same log with the damaged lines removed
    with pytest.warns(DamagedRecordsWarning):
        log = read_nmea(path)
    assert log.n_damaged == n_bad
    assert log.n_ignored == clean.n_ignored
    for a, b in [
        (log.positions, clean.positions),
        (log.velocities, clean.velocities),
        (log.headings, clean.headings),
    ]:
        for name in a.__dataclass_fields__:
            np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
