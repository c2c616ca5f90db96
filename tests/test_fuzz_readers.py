"""Byte-mutation fuzz of every reader on its real file: flip, insert and delete bytes, cut the
file. A reader may warn (DamagedRecordsWarning) or, when nothing usable is left, raise
ValueError; anything else fails. What it keeps is bounded below: each mutated byte damages at
most a couple of records, so nothing valid is lost beyond them.
"""

from __future__ import annotations

import os
import warnings
from importlib import resources
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from usvfast.bearing import io as bio
from usvfast.datasets import load_joyride
from usvfast.fusion import read_ais_feed
from usvfast.lidar import VelodynePcapReader
from usvfast.nav.ais import read_ais
from usvfast.nav.nmea import read_nmea
from usvfast.radar import read_radar_csv, read_radar_nmea

from conftest import SHARED_DATA

NMEA = SHARED_DATA / "nmea"
PCAP = SHARED_DATA / "lidar" / "velodyne_hdl32e.pcap"
JOYRIDE_MAT = SHARED_DATA / "joyride" / "joyride.mat"
BUNDLED = resources.files("usvfast") / "data" / "bearing"
EXAMPLES = int(os.environ.get("USVFAST_FUZZ_EXAMPLES", "40"))
FUZZ = settings(
    max_examples=EXAMPLES,
    deadline=None,
    database=None,
    derandomize=not os.environ.get("USVFAST_FUZZ_RANDOM"),
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
)


@st.composite
def mutations(draw, size: int):
    """A list of (kind, position, byte) edits and an optional cut length."""
    edits = draw(
        st.lists(
            st.tuples(
                st.sampled_from(["flip", "set", "insert", "delete"]),
                st.integers(0, size - 1),
                st.integers(0, 255),
            ),
            min_size=1,
            max_size=4,
        )
    )
    cut = draw(st.one_of(st.none(), st.integers(size // 2, size)))
    return edits, cut


def mutate(data: bytes, edits, cut) -> bytes:
    b = bytearray(data)
    for kind, pos, value in edits:
        pos = min(pos, len(b) - 1)
        if kind == "flip":
            b[pos] ^= 1 << (value % 8)
        elif kind == "set":
            b[pos] = value
        elif kind == "insert":
            b.insert(pos, value)
        elif len(b) > 1:
            del b[pos]
    return bytes(b[:cut] if cut is not None else b)


def read_quietly(fn, path):
    """(result or None when the reader said nothing usable is left, warnings)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            return fn(path)
        except ValueError:
            return None


def kept_lines(data: bytes, edits, cut) -> int:
    """Lines of `data` that no edit touched and the cut kept (each edit touches at most the
    line it is in and, for a deleted/inserted newline, its neighbour)."""
    end = len(data) if cut is None else cut
    lines, pos, touched = [], 0, set()
    for ln in data.splitlines(keepends=True):
        lines.append((pos, pos + len(ln)))
        pos += len(ln)
    for _, p, _ in edits:
        for k, (a, b) in enumerate(lines):
            if a <= p < b:
                touched.update({k - 1, k, k + 1})
    return sum(1 for k, (a, b) in enumerate(lines) if k not in touched and b <= end - 2)


def fuzz_line_reader(path, data: bytes, reader, count, want: int) -> None:
    """Byte-mutate `data` into `path` and read it: `reader` returns, warns or raises
    ValueError, and keeps `count(result) >= want - (lines the edits touched or cut)`."""
    n_lines = sum(1 for _ in data.splitlines())

    @FUZZ
    @given(mutations(len(data)))
    def run(m):
        edits, cut = m
        path.write_bytes(mutate(data, edits, cut))
        got = read_quietly(reader, path)
        if got is not None:
            assert count(got) >= want - (n_lines - kept_lines(data, edits, cut))

    run()


@pytest.mark.parametrize("name", ["saab-r4.log", "sirfstarv-nmea.log", "ublox-zed-f9p-nmea.log"])
def test_fuzz_nmea(tmp_path_factory, name):
    data = (NMEA / name).read_bytes()
    intact = read_nmea(NMEA / name)
    good = intact.n_sentences if hasattr(intact, "n_sentences") else None
    path = tmp_path_factory.mktemp("nmea") / name

    @FUZZ
    @given(mutations(len(data)))
    def run(m):
        edits, cut = m
        path.write_bytes(mutate(data, edits, cut))
        log = read_quietly(read_nmea, path)
        if log is None:
            return
        # each edit costs at most a few sentences' fixes; the rest is read as before
        assert len(log.positions.time) >= len(intact.positions.time) * 0.5 - 4 * len(edits)

    run()
    del good


def test_fuzz_ais(tmp_path):
    data = (NMEA / "sample.aivdm").read_bytes()
    intact = read_quietly(read_ais, NMEA / "sample.aivdm")
    # a multi-part message spans up to 3 lines: a touched line costs at most one message
    fuzz_line_reader(
        tmp_path / "x.aivdm", data, read_ais, lambda g: g.n_messages, intact.n_messages
    )


@pytest.mark.parametrize(
    ("name", "reader"), [("samples.csv", bio.read_bearing_samples), ("ais.csv", bio.read_ais)]
)
def test_fuzz_csv(tmp_path, name, reader):
    data = (BUNDLED / name).read_bytes()

    def rows(r):
        return len(r.times) if hasattr(r, "times") else len(r.own.times) + len(r.target.times)

    intact = rows(read_quietly(reader, BUNDLED / name))
    fuzz_line_reader(tmp_path / name, data, reader, rows, intact)


def test_fuzz_pcap(tmp_path):
    data = PCAP.read_bytes()
    intact = list(VelodynePcapReader(PCAP))
    total = sum(len(f) for f in intact)
    path = tmp_path / "x.pcap"

    @FUZZ
    @given(mutations(len(data)))
    def run(m):
        edits, cut = m
        path.write_bytes(mutate(data, edits, cut))
        frames = read_quietly(lambda p: list(VelodynePcapReader(p)), path)
        if frames is None:
            return
        # an edit damages at most two records (~384 points each) ...
        budget = 2 * 384 * len(edits)
        if cut is not None:  # ... and the cut drops everything after it
            budget += int(total * (len(data) - cut) / len(data)) + 2 * 384
        assert sum(len(f) for f in frames) >= total - budget

    run()


def test_fuzz_joyride(tmp_path):
    src = SHARED_DATA / "joyride" / "joyride.mat"
    data = src.read_bytes()
    path = tmp_path / "joyride.mat"

    @FUZZ
    @given(mutations(len(data)))
    def run(m):
        path.write_bytes(mutate(data, *m))
        read_quietly(load_joyride, path)  # a damaged .mat: ValueError or data, nothing else

    run()


def test_fuzz_ais_feed(tmp_path):
    # The fusion's AIS feed on the real mixed log: AIS timed from the log's own ZDA/RMC clock.
    data = (NMEA / "saab-r4.log").read_bytes()

    def timed(feed):
        return int(np.isfinite(feed.log.positions.time).sum())

    intact = timed(read_quietly(read_ais_feed, NMEA / "saab-r4.log"))
    fuzz_line_reader(tmp_path / "feed.log", data, read_ais_feed, timed, intact)


def _joyride_rows(n_scans: int = 150) -> list[tuple[float, float, float]]:
    jr = load_joyride(SHARED_DATA / "joyride" / "joyride.mat")
    rows = []
    for t, scan in list(zip(jr.times, jr.measurements, strict=True))[:n_scans]:
        rows += [(float(t), float(n), float(e)) for n, e in scan]
    return rows


def test_fuzz_radar_csv(tmp_path):
    # The real Joyride radar plots as a (time, north, east) CSV; a damaged time (one jumping
    # ahead included) costs its own row, not the rows after it.
    rows = _joyride_rows()
    body = "".join(f"{t:.3f},{n:.2f},{e:.2f}\n" for t, n, e in rows)
    data = ("time,north,east\n" + body).encode()
    (tmp_path / "plots.csv").write_bytes(data)
    assert len(read_quietly(read_radar_csv, tmp_path / "plots.csv")) == len(rows)
    fuzz_line_reader(tmp_path / "x.csv", data, read_radar_csv, len, len(rows))


def _ttm(number: int, dist_nm: float, bearing: float, hhmmss: str) -> str:
    import pynmea2

    f = [f"{number:02d}", f"{dist_nm:.4f}", f"{bearing:.1f}", "T", "5.0", "90.0", "T", "0.1"]
    f += ["1.0", "N", "", "T", "", hhmmss, "A"]
    return str(pynmea2.TalkerSentence("RA", "TTM", f))


def test_fuzz_radar_nmea(tmp_path):
    # ARPA TTM sentences of the real Joyride plots (range and bearing from the origin), timed by
    # a ZDA clock every scan, as an ARPA radar's NMEA output would carry them.
    import datetime as dt

    import pynmea2

    lines = []
    for t, n, e in _joyride_rows(100):
        stamp = dt.datetime.fromtimestamp(t, dt.timezone.utc)
        hhmmss = stamp.strftime("%H%M%S.") + f"{stamp.microsecond // 10000:02d}"
        zda = [hhmmss, f"{stamp.day:02d}", f"{stamp.month:02d}", str(stamp.year), "00", "00"]
        lines.append(str(pynmea2.TalkerSentence("GP", "ZDA", zda)))
        rng, brg = float(np.hypot(n, e)) / 1852.0, float(np.degrees(np.arctan2(e, n))) % 360.0
        lines.append(_ttm(len(lines) % 99, rng, brg, hhmmss))
    data = ("\n".join(lines) + "\n").encode()
    src, path = tmp_path / "arpa.nmea", tmp_path / "x.nmea"
    src.write_bytes(data)
    intact = read_quietly(read_radar_nmea, src)
    assert len(intact) == len(lines) // 2
    # a touched line costs its plot, or (a ZDA) the plot timed by it
    fuzz_line_reader(path, data, read_radar_nmea, len, len(intact))


@st.composite
def text_mutations(draw, text: str):
    """A TOML text with one to three edits: a line deleted, duplicated or changed by a
    character, or a value replaced by another TOML value."""
    lines = text.splitlines()
    for _ in range(draw(st.integers(1, 3))):
        k = draw(st.integers(0, len(lines) - 1))
        kind = draw(st.sampled_from(["delete", "duplicate", "char", "value"]))
        if kind == "delete" and len(lines) > 1:
            del lines[k]
        elif kind == "duplicate":
            lines.insert(k, lines[k])
        elif kind == "char" and lines[k]:
            i = draw(st.integers(0, len(lines[k]) - 1))
            c = draw(st.sampled_from(list('=[]"., 0x\\#\x00é{}')))
            lines[k] = lines[k][:i] + c + lines[k][i + 1 :]
        elif "=" in lines[k]:
            value = draw(
                st.sampled_from(
                    ["nan", "inf", "-1", "0", "1e308", '""', '"x"', "[]", "[1, 2]", "{}", "true"]
                )
            )
            lines[k] = lines[k].split("=", 1)[0] + "= " + value
    return "\n".join(lines) + "\n"


@pytest.mark.parametrize(
    "source",
    [
        resources.files("usvfast") / "data" / "harbour" / "recording.toml",
        resources.files("usvfast") / "pipeline" / "presets" / "thesis.toml",
    ],
    ids=["harbour", "thesis-preset"],
)
def test_fuzz_pipeline_config(tmp_path, source):
    # The pipeline's config loader on fuzzed TOML: a ConfigError (a ValueError naming the key)
    # or a config, never another exception. The folder holds the recording's files.
    from usvfast.pipeline.config import load_config

    text = source.read_text()
    folder = Path(str(source)).parent
    target = tmp_path / "config.toml"
    for name in ("bag", "camera_info.yaml", "truth.csv"):  # the recording's relative paths
        if (folder / name).exists():
            (tmp_path / name).symlink_to(folder / name)

    @FUZZ
    @given(text_mutations(text))
    def run(mutated):
        target.write_text(mutated, encoding="utf-8")
        try:
            load_config(target)
        except ValueError:
            pass

    run()


def test_fuzz_sweep_spec(tmp_path):
    # The sweep spec loader on the repository's Joyride sweep, fuzzed.
    from usvfast.sweep.spec import load_spec

    src = Path(__file__).parents[1] / "configs" / "sweep-joyride.toml"
    text = src.read_text().replace("../tests/data/joyride/joyride.mat", str(JOYRIDE_MAT))
    path = tmp_path / "spec.toml"

    @FUZZ
    @given(text_mutations(text))
    def run(mutated):
        path.write_text(mutated, encoding="utf-8")
        try:
            load_spec(path, tmp_path / "out")
        except ValueError:
            pass

    run()
