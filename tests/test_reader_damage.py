"""Text readers on damaged field files: one bad byte, line or glue costs one record, never the
file; inputs that are not regular files are refused instead of hanging or filling memory."""

from __future__ import annotations

import os
import warnings
from importlib import resources
from pathlib import Path

import numpy as np
import pytest

from usvfast._damage import DamagedRecordsWarning
from usvfast._files import MAX_LINE_BYTES
from usvfast.bearing import io as bio
from usvfast.nav.ais import read_ais
from usvfast.nav.nmea import read_nmea

from conftest import SHARED_DATA

BUNDLED = resources.files("usvfast") / "data" / "bearing"
NMEA = SHARED_DATA / "nmea"


def quiet(fn, *args):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        out = fn(*args)
    return out, [w for w in caught if issubclass(w.category, DamagedRecordsWarning)]


@pytest.mark.parametrize(
    ("name", "reader"),
    [("samples.csv", bio.read_bearing_samples), ("ais.csv", bio.read_ais)],
)
@pytest.mark.parametrize(
    "damage",
    [
        lambda line: line[:5] + b"\xff\xfe" + line[5:],  # a byte that is not UTF-8
        lambda line: line.rstrip(b"\n") + b"," + b"9" * (MAX_LINE_BYTES + 10) + b"\n",
        lambda line: line.rstrip(b"\n") + b',"' + b"x" * 200_000 + b'"\n',  # > csv field limit
        lambda line: line[:3] + b"\x00" + line[3:],  # a NUL byte
    ],
    ids=["non-utf8", "over-long-line", "over-long-field", "nul"],
)
def test_csv_damaged_line_costs_one_row(tmp_path, name, reader, damage):
    lines = (BUNDLED / name).read_bytes().splitlines(keepends=True)
    intact, _ = quiet(reader, BUNDLED / name)
    victim = len(lines) // 2
    bad = tmp_path / name
    bad.write_bytes(b"".join([*lines[:victim], damage(lines[victim]), *lines[victim + 1 :]]))
    ref = tmp_path / ("ref-" + name)
    ref.write_bytes(b"".join([*lines[:victim], *lines[victim + 1 :]]))
    got, caught = quiet(reader, bad)
    want, _ = quiet(reader, ref)
    assert caught and got.skipped == want.skipped + 1
    if name == "samples.csv":
        np.testing.assert_array_equal(got.times, want.times)
        np.testing.assert_array_equal(got.bearing_deg, want.bearing_deg)
        assert len(got.times) == len(intact.times) - 1
    else:
        np.testing.assert_array_equal(got.own.times, want.own.times)
        np.testing.assert_array_equal(got.target.times, want.target.times)


def test_ais_glued_sentences_are_both_read(tmp_path):
    lines = [ln for ln in (NMEA / "sample.aivdm").read_bytes().splitlines() if ln.startswith(b"!")]
    intact, _ = quiet(read_ais, [ln + b"\n" for ln in lines])
    glued = [lines[0] + lines[1] + b"\n"] + [ln + b"\n" for ln in lines[2:]]  # a lost newline
    got, _ = quiet(read_ais, glued)
    assert got.n_sentences == intact.n_sentences
    assert got.n_messages == intact.n_messages
    np.testing.assert_array_equal(got.positions.mmsi, intact.positions.mmsi)


def test_ais_comment_glued_to_a_sentence_keeps_the_sentence():
    lines = [ln for ln in (NMEA / "sample.aivdm").read_bytes().splitlines() if ln.startswith(b"!")]
    intact, _ = quiet(read_ais, [ln + b"\n" for ln in lines])
    glued = [b"# receiver restarted" + lines[0] + b"\n"] + [ln + b"\n" for ln in lines[1:]]
    got, _ = quiet(read_ais, glued)
    assert got.n_messages == intact.n_messages
    # a comment that quotes a sentence (as GPSD's files do) stays a comment
    quoted, _ = quiet(read_ais, [b"# " + lines[0] + b"\n"] + [ln + b"\n" for ln in lines[1:]])
    assert quoted.n_messages == intact.n_messages - 1


def test_ais_in_a_mixed_nmea_log_is_timed_from_the_logs_clock():
    log, _ = quiet(read_ais, NMEA / "saab-r4.log")
    nav = read_nmea(NMEA / "saab-r4.log")
    p = log.positions
    assert len(p.time) >= 2 and np.isfinite(p.time).all()
    # within a second of the log's own fixes, and on the report's own UTC second
    span = nav.positions.time
    assert span.min() - 60 <= p.time.min() and p.time.max() <= span.max() + 60
    valid = p.second < 60
    assert valid.any()
    np.testing.assert_array_equal(np.mod(p.time[valid], 60), p.second[valid])


def test_over_long_nmea_line_is_one_damaged_line(tmp_path):
    text = (NMEA / "saab-r4.log").read_bytes()
    bad = tmp_path / "long.log"
    bad.write_bytes(text[:200] + b"$GPGGA," + b"1" * (MAX_LINE_BYTES * 3) + b"\n" + text[200:])
    ref = read_nmea(NMEA / "saab-r4.log")
    got, _ = quiet(read_nmea, bad)
    assert got.n_damaged >= ref.n_damaged + 1
    assert len(got.positions.time) >= len(ref.positions.time) - 1


@pytest.mark.parametrize("kind", ["directory", "fifo", "device"])
@pytest.mark.parametrize(
    "reader",
    [read_nmea, read_ais, bio.read_bearing_samples, bio.read_ais],
    ids=lambda f: f.__module__ + "." + f.__name__,
)
def test_non_regular_files_are_refused(tmp_path, kind, reader):
    if kind == "directory":
        path = tmp_path
    elif kind == "fifo":
        path = tmp_path / "pipe"
        os.mkfifo(path)
    else:
        path = Path("/dev/zero")
    with pytest.raises(ValueError, match="not a regular file"):
        reader(path)


@pytest.mark.parametrize("jump", [1e6, -1e6])  # a damaged digit: far in the future or the past
def test_one_damaged_radar_time_costs_one_row(tmp_path, jump):
    # Real Joyride plots as a CSV: one time jumping ahead used to make every later (correct)
    # row "earlier than the previous" and lose the rest of the file.
    from usvfast.datasets import load_joyride
    from usvfast.radar import read_radar_csv

    jr = load_joyride(SHARED_DATA / "joyride" / "joyride.mat")
    rows = [
        (t, n, e) for t, m in zip(jr.times[:60], jr.measurements[:60], strict=True) for n, e in m
    ]
    text = ["time,north,east"] + [f"{t:.3f},{n:.2f},{e:.2f}" for t, n, e in rows]
    k = len(rows) // 3
    t, n, e = rows[k]
    text[k + 1] = f"{t + jump:.3f},{n:.2f},{e:.2f}"
    (tmp_path / "p.csv").write_text("\n".join(text) + "\n")
    got, warned = quiet(read_radar_csv, tmp_path / "p.csv")
    assert len(got) == len(rows) - 1 and got.n_damaged == 1 and warned
    want = [round(r[0], 3) for i, r in enumerate(rows) if i != k]
    np.testing.assert_allclose(got.time, want, rtol=0, atol=1e-6)


def test_time_order_keeps_the_longest_earliest_run():
    # The rows kept = the longest non-decreasing subsequence (earliest among equals), checked
    # against a brute-force search over every subset.
    import itertools
    import random

    from usvfast.radar.readers import _in_time_order

    def brute(t):
        for size in range(len(t), 0, -1):
            for c in itertools.combinations(range(len(t)), size):
                if all(t[c[j]] <= t[c[j + 1]] for j in range(size - 1)):
                    return list(c)
        return []

    rng = random.Random(1)
    for _ in range(500):
        t = [float(rng.randint(0, 5)) for _ in range(rng.randint(0, 8))]
        assert _in_time_order(t) == brute(t), t
