"""The `ais` stream type: receive times from tag blocks or a leading UNIX time, real AIS
sentences (GPSD's sample.aivdm) decoded by the AIS reader, reports merged with other streams;
untimed and damaged lines counted. pyais decodes the same sentences as the reference."""

from __future__ import annotations

import math

import pyais
import pytest
from typer.testing import CliRunner

from usvfast.cli import app
from usvfast.nav._damage import DamagedRecordsWarning
from usvfast.nav.ais_stream import AisReport
from usvfast.nav.inspect import summarize_ais
from usvfast.nav.linetime import line_time
from usvfast.nav.replay import Replay, load_recording

from conftest import SHARED_DATA

NMEA_DATA = SHARED_DATA / "nmea"
T0 = 1_686_909_600


def _sample_lines():
    lines = (NMEA_DATA / "sample.aivdm").read_text().splitlines()
    return [x.strip() for x in lines if x.startswith("!AIVDM,1,1,") and x[11] in ",0123456789"]


def _tag(t: int) -> str:
    body = f"c:{t}"
    cs = 0
    for ch in body:
        cs ^= ord(ch)
    return f"\\{body}*{cs:02X}\\"


def test_receive_time_formats():
    assert line_time(b"\\s:rx,c:1686909600*00\\!AIVDM,1,1,,A,x,0*00") == 1686909600.0
    assert line_time(b"\\c:1686909600500*00\\!AIVDM") == 1686909600.5  # milliseconds
    assert line_time(b"1686909600.25 !AIVDM,1,1") == 1686909600.25
    assert line_time(b"1686909600;!AIVDM,1,1") == 1686909600.0
    assert math.isnan(line_time(b"!AIVDM,1,1,,A,x,0*00"))


def test_ais_stream_in_replay(tmp_path):
    # Single-fragment position reports from the real sample, with receive times.
    singles = [x for x in _sample_lines() if x.split(",")[5][0] in "13B"]
    assert len(singles) >= 4
    lines, want = [], []
    for i, line in enumerate(singles[:8]):
        t = T0 + 2 * i
        lines.append(f"{_tag(t)}{line}" if i % 2 else f"{t}.0 {line}")
        decoded = pyais.NMEAMessage(line.encode()).decode()
        want.append((float(t), decoded.mmsi, decoded.lat, decoded.lon))
    lines.insert(3, singles[0])  # no receive time: untimed
    lines.insert(5, f"{T0 + 5} !AIVDM,1,1,,A,15RTgt0PAso;90TKcjM8h6g208CQ,0*4B")  # bad checksum
    (tmp_path / "ais.log").write_text("\n".join(lines) + "\n")
    (tmp_path / "rec.toml").write_text(
        '[[stream]]\nid = "ais"\ntype = "ais"\npath = "ais.log"\nclock_offset = 0.5\n'
    )
    replay = Replay(load_recording(tmp_path / "rec.toml"))
    with pytest.warns(DamagedRecordsWarning):
        items = list(replay)
    assert replay.counts["ais"].damaged == 2
    assert all(isinstance(it.data, AisReport) for it in items)
    got = [(it.time - 0.5, it.data.mmsi, it.data.lat_deg, it.data.lon_deg) for it in items]
    assert [g[:2] for g in got] == [w[:2] for w in want]
    for g, w in zip(got, want, strict=True):
        assert g[2] == pytest.approx(w[2], abs=1e-9) and g[3] == pytest.approx(w[3], abs=1e-9)
    res = CliRunner().invoke(app, ["inspect", str(tmp_path / "rec.toml")])
    assert res.exit_code == 0, res.output
    row = next(x for x in res.output.splitlines() if x.count("│") > 5 and "ais.log" in x)
    cells = [c.strip() for c in row.split("│")[1:-1]]
    assert cells[3] == str(len(want)) and cells[-1] == "2"


def test_untimed_ais_file_is_decoded_and_summarised():
    # GPSD's sample has no receive times: inspect still decodes it; pyais is the reference.
    path = NMEA_DATA / "sample.aivdm"
    want: dict[int, int] = {}
    lat, mmsis = [], set()
    with pyais.FileReaderStream(str(path)) as stream:
        for msg in stream:
            d = msg.decode().asdict()
            want[d["msg_type"]] = want.get(d["msg_type"], 0) + 1
            if d["msg_type"] in (1, 2, 3, 18, 19, 27, 5, 24):
                mmsis.add(d["mmsi"])
            if d["msg_type"] in (1, 2, 3, 18, 19, 27) and d.get("lat") not in (None, 91.0):
                lat.append(d["lat"])
    c = summarize_ais(path)
    assert c.by_type == dict(sorted(want.items())) and c.messages == sum(want.values())
    assert len(c.by_type) == 27 and c.mmsis == len(mmsis) and c.timed == 0
    assert c.with_position == len(lat) and c.lat_range == (min(lat), max(lat))
    res = CliRunner().invoke(app, ["inspect", str(path)])
    assert res.exit_code == 0, res.output
    assert f"{c.messages} messages" in res.output and "no receive times" in res.output
    assert "long-range position report" in res.output
