"""Byte-mutation fuzz of every reader on its real file: flip, insert and delete bytes, cut the
file. A reader may warn (DamagedRecordsWarning) or, when nothing usable is left, raise
ValueError; anything else fails. What it keeps is bounded below: each mutated byte damages at
most a couple of records, so nothing valid is lost beyond them.
"""

from __future__ import annotations

import os
import warnings
from importlib import resources

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from usvfast.bearing import io as bio
from usvfast.datasets import load_joyride
from usvfast.lidar import VelodynePcapReader
from usvfast.nav.ais import read_ais
from usvfast.nav.nmea import read_nmea

from conftest import SHARED_DATA

NMEA = SHARED_DATA / "nmea"
PCAP = SHARED_DATA / "lidar" / "velodyne_hdl32e.pcap"
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
    path = tmp_path / "x.aivdm"

    @FUZZ
    @given(mutations(len(data)))
    def run(m):
        edits, cut = m
        path.write_bytes(mutate(data, edits, cut))
        log = read_quietly(read_ais, path)
        if log is None:
            return
        lost_lines = sum(1 for _ in data.splitlines()) - kept_lines(data, edits, cut)
        # a multi-part message spans up to 3 lines: a touched line costs at most one message
        assert log.n_messages >= intact.n_messages - lost_lines

    run()


@pytest.mark.parametrize(
    ("name", "reader"), [("samples.csv", bio.read_bearing_samples), ("ais.csv", bio.read_ais)]
)
def test_fuzz_csv(tmp_path, name, reader):
    data = (BUNDLED / name).read_bytes()
    intact = read_quietly(reader, BUNDLED / name)
    path = tmp_path / name

    def rows(r):
        return len(r.times) if hasattr(r, "times") else len(r.own.times) + len(r.target.times)

    @FUZZ
    @given(mutations(len(data)))
    def run(m):
        edits, cut = m
        path.write_bytes(mutate(data, edits, cut))
        got = read_quietly(reader, path)
        if got is None:
            return
        touched = sum(1 for _ in data.splitlines()) - kept_lines(data, edits, cut)
        assert rows(got) >= rows(intact) - touched

    run()


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
