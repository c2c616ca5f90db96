"""Navigation inputs of the pipeline beyond GGA/RMC/HDT + IMU: roll and pitch from NMEA
attitude sentences (PASHR, XDR; pynmea2 renders and parses them), and a NavSatFix topic with
the heading from another stream. Positions are made with pymap3d (the peer for the geodesy),
the expected pose is the known vessel motion."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pymap3d
import pynmea2
import pytest
from nav_config import nav_config

from usvfast._damage import DamagedRecordsWarning
from usvfast.pipeline import NavigationError, Pipeline, load_config
from usvfast.pipeline.attitude import attitude_from_sentence, read_attitude_sentences
from usvfast.pipeline.live_pose import parse_sentence
from usvfast.pipeline.pose import NavTrack

T0 = 1_686_960_000.0  # 2023-06-16 23:59:00 UTC: the log crosses midnight
ORIGIN = (63.44, 10.40, 0.0)
LEVER = (-0.94, 0.0, 0.0)


def nmea(talker: str, kind: str, fields: list[str]) -> str:
    """A sentence with its checksum, rendered by pynmea2."""
    if talker == "P":  # kind "ASHR": manufacturer ASH, sentence R
        msg = pynmea2.ProprietarySentence(kind[:3], [kind[3:], *fields])
    else:
        msg = pynmea2.TalkerSentence.sentence_types[kind](talker, kind, tuple(fields))
    return msg.render(checksum=True, dollar=True)


def hms(t: float) -> str:
    s = t % 86400.0
    return f"{int(s // 3600):02d}{int(s % 3600 // 60):02d}{s % 60:06.3f}"


def motion(t: np.ndarray | float):
    """Vessel reference point: 0.5 m/s north, heading 20 deg + 1 deg/s, rolling and pitching."""
    dt = np.asarray(t, dtype=np.float64) - T0
    return (
        0.5 * dt,
        0.1 * dt,
        np.radians(20.0 + 1.0 * dt),
        np.radians(3.0 * np.sin(dt)),
        np.radians(-2.0 * np.cos(dt)),
    )


def antenna_latlon(t: float) -> tuple[float, float]:
    n, e, h, _, _ = motion(t)
    an = n + math.cos(h) * LEVER[0] - math.sin(h) * LEVER[1]
    ae = e + math.sin(h) * LEVER[0] + math.cos(h) * LEVER[1]
    lat, lon, _ = pymap3d.ned2geodetic(an, ae, 0.0, *ORIGIN)
    return float(lat), float(lon)


def ddmm(value: float, lat: bool) -> tuple[str, str]:
    v = abs(value)
    d = int(v)
    text = f"{d:02d}{(v - d) * 60:010.7f}" if lat else f"{d:03d}{(v - d) * 60:010.7f}"
    return text, ("N" if value >= 0 else "S") if lat else ("E" if value >= 0 else "W")


def epoch_sentences(t: float, xdr: bool) -> list[str]:
    import datetime as dt

    lat, lon = antenna_latlon(t)
    _, _, h, roll, pitch = motion(t)
    day = dt.datetime.fromtimestamp(t, dt.timezone.utc).strftime("%d%m%y")
    la, lh = ddmm(lat, True)
    lo, loh = ddmm(lon, False)
    out = [
        nmea("GP", "GGA", [hms(t), la, lh, lo, loh, "4", "12", "1", "10", "M", "40", "M", "", ""]),
        nmea("GP", "RMC", [hms(t), "A", la, lh, lo, loh, "0.97", "20.0", day, "", "", "A"]),
        nmea("GP", "HDT", [f"{math.degrees(h) % 360:.3f}", "T"]),
    ]  # fmt: skip
    r, p = math.degrees(roll), math.degrees(pitch)
    if xdr:
        out.append(nmea("II", "XDR", ["A", f"{p:.3f}", "D", "PITCH", "A", f"{r:.3f}", "D", "ROLL"]))
    else:
        fields = [hms(t), f"{math.degrees(h) % 360:.2f}", "T", f"{r:+.3f}", f"{p:+.3f}"]
        out.append(nmea("P", "ASHR", [*fields, "+0.00", "0.10", "0.10", "0.20", "1", "0"]))
    return out


def test_attitude_sentences_parse_and_refuse_damage():
    fields = ["120000.00", "90.0", "T", "-1.50", "+2.25", "0", "0", "0", "0", "1", "0"]
    pashr = nmea("P", "ASHR", fields)
    assert type(pynmea2.parse(pashr)).__name__ == "ASHRATT"
    roll, pitch = attitude_from_sentence(pashr)
    assert math.degrees(roll) == pytest.approx(-1.5) and math.degrees(pitch) == pytest.approx(2.25)
    fields = ["A", "2.0", "D", "PTCH", "C", "20.1", "C", "AIR", "A", "-0.5", "D", "ROLL"]
    xdr = nmea("II", "XDR", fields)
    roll, pitch = attitude_from_sentence(xdr)
    assert math.degrees(roll) == pytest.approx(-0.5) and math.degrees(pitch) == pytest.approx(2.0)
    assert parse_sentence(xdr) == ("attitude", attitude_from_sentence(xdr))
    bad = pashr[:-2] + ("00" if pashr[-2:] != "00" else "11")  # wrong checksum
    assert attitude_from_sentence(bad) is None
    assert attitude_from_sentence(nmea("II", "XDR", ["A", "2.0", "D", "PITCH"])) is None
    assert attitude_from_sentence(nmea("GP", "HDT", ["10.0", "T"])) is None
    t, _, _, damaged = read_attitude_sentences([pashr, bad, "garbage"], reference=T0)
    assert t.size == 1 and damaged == 1
    with pytest.raises(ValueError, match="reference"):
        read_attitude_sentences([pashr], reference=math.nan)


def _config(tmp_path: Path, streams: str, navigation: str, attitude: str) -> Path:
    recording = f'navigation = {navigation}\nattitude = "{attitude}"\n'
    return nav_config(tmp_path, recording + f"origin = [{ORIGIN[0]}, {ORIGIN[1]}, 0.0]", streams)


def _check_track(track: NavTrack, times: np.ndarray, roll_too: bool = True) -> None:
    for t in times:
        pose = track.pose_at(float(t))
        n, e, h, roll, pitch = motion(t)
        assert pose.north == pytest.approx(n, abs=2e-3) and pose.east == pytest.approx(e, abs=2e-3)
        assert abs((pose.heading - h + math.pi) % (2 * math.pi) - math.pi) < 2e-4
        if roll_too:
            # linear interpolation of 10 Hz samples of a 1 rad/s sine: ~ (0.1)^2 / 8 of 3 deg
            assert math.degrees(pose.roll) == pytest.approx(math.degrees(roll), abs=4e-3)
            assert math.degrees(pose.pitch) == pytest.approx(math.degrees(pitch), abs=4e-3)


@pytest.mark.parametrize("xdr", [False, True])
def test_nmea_log_with_attitude_across_midnight(tmp_path, xdr):
    times = T0 + 0.1 * np.arange(1201)  # 23:59:00 -> 00:01:00
    lines = [s for t in times for s in epoch_sentences(float(t), xdr)]
    lines.insert(50, lines[47][:-3] + "*00")  # a damaged attitude or position sentence
    (tmp_path / "gnss.nmea").write_text("\n".join(lines) + "\n")
    streams = f"""
[[stream]]
id = "gnss"
type = "nmea"
path = "gnss.nmea"
[stream.mount]
lever_arm = {list(LEVER)}
"""
    cfg = load_config(_config(tmp_path, streams, '"gnss"', "gnss"))
    with pytest.warns(DamagedRecordsWarning, match="skipped 1 damaged"):
        track = NavTrack.from_config(cfg)
    probe = T0 + np.array([0.05, 37.33, 59.97, 60.02, 88.8, 119.95])  # across midnight
    _check_track(track, probe)
    # the damaged sentence counts once (the position and the attitude reader both saw it)
    assert track.damaged["gnss"] == 1


def _write_fix_bag(path: Path, times: np.ndarray, *, attitude: bool) -> None:
    from rosbags.rosbag2 import Writer

    from usvfast.lidar.readers import make_header
    from usvfast.nav.bags import bag_typestore

    store = bag_typestore()
    T = store.types
    with Writer(path, version=8) as w:
        c_fix = w.add_connection("/fix", "sensor_msgs/msg/NavSatFix", typestore=store)
        c_hdt = w.add_connection("/heading", "nmea_msgs/msg/Sentence", typestore=store)
        for k, t in enumerate(times):
            lat, lon = antenna_latlon(float(t))
            fix = T["sensor_msgs/msg/NavSatFix"](
                header=make_header(store, float(t), "gnss"),
                status=T["sensor_msgs/msg/NavSatStatus"](status=-1 if k == 5 else 0, service=1),
                latitude=lat,
                longitude=lon,
                altitude=40.0,
                position_covariance=np.zeros(9),
                position_covariance_type=0,
            )
            ns = round(float(t) * 1e9)
            w.write(c_fix, ns, store.serialize_cdr(fix, "sensor_msgs/msg/NavSatFix"))
            # HDT and XDR carry no time: the message stamps time them.
            for s in epoch_sentences(float(t), xdr=True)[2 : 4 if attitude else 3]:
                msg = T["nmea_msgs/msg/Sentence"](
                    header=make_header(store, float(t), "gnss"), sentence=s
                )
                w.write(c_hdt, ns, store.serialize_cdr(msg, "nmea_msgs/msg/Sentence"))


def test_navsatfix_with_heading_from_another_topic(tmp_path):
    times = T0 + 0.1 * np.arange(200)
    _write_fix_bag(tmp_path / "bag", times, attitude=True)
    streams = f"""
[[stream]]
id = "fix"
type = "bag"
path = "bag"
topic = "/fix"
[stream.mount]
lever_arm = {list(LEVER)}

[[stream]]
id = "heading"
type = "bag"
path = "bag"
topic = "/heading"
"""
    cfg = load_config(_config(tmp_path, streams, '["fix", "heading"]', "heading"))
    track = NavTrack.from_config(cfg)
    _check_track(track, T0 + np.array([0.35, 4.0, 10.01, 19.5]))
    # Live: the same messages one at a time through Pipeline.process.
    from usvfast.nav.bags import BagTopic

    pipe = Pipeline(cfg)
    msgs = [
        (m.time, sid, m.data) for sid, topic in (("fix", "/fix"), ("heading", "/heading"))
        for m in BagTopic(tmp_path / "bag", topic)
    ]  # fmt: skip
    for t, sid, data in sorted(msgs, key=lambda m: m[0]):
        if t > T0 + 10.0:
            break

        class Msg:
            pass

        msg = Msg()
        msg.time, msg.stream, msg.data = t, sid, data
        assert pipe.process(msg) == []
    live = pipe.live.at(T0 + 9.95)
    ref = track.pose_at(T0 + 9.95)
    assert live.north == pytest.approx(ref.north, abs=1e-6)
    assert live.heading == pytest.approx(ref.heading, abs=1e-9)
    assert live.roll == pytest.approx(ref.roll, abs=1e-9)
    assert live.pitch == pytest.approx(ref.pitch, abs=1e-9)


def test_navsatfix_without_heading_or_attitude_names_the_streams(tmp_path):
    times = T0 + 0.1 * np.arange(30)
    _write_fix_bag(tmp_path / "bag", times, attitude=False)
    streams = """
[[stream]]
id = "fix"
type = "bag"
path = "bag"
topic = "/fix"
[[stream]]
id = "heading"
type = "bag"
path = "bag"
topic = "/heading"
"""
    cfg = load_config(_config(tmp_path, streams, '["fix"]', "heading"))
    with pytest.raises(NavigationError, match=r"no heading.*'fix'"):
        NavTrack.from_config(cfg)
    cfg = load_config(_config(tmp_path, streams, '["fix", "heading"]', "heading"))
    with pytest.raises(NavigationError, match="attitude stream 'heading': no roll/pitch"):
        NavTrack.from_config(cfg)
