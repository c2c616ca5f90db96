"""One warning class for damaged field data: every reader's warning is (a subclass of)
usvfast._damage.DamagedRecordsWarning, importable under its old names; the shared counter."""

from __future__ import annotations

import warnings

import pytest

import usvfast.nav._damage as nav_damage
import usvfast.nav.nmea as nmea
from usvfast._damage import DamageCounter, DamagedRecordsWarning
from usvfast.bearing.io import SkippedRowsWarning
from usvfast.lidar import LidarDataWarning


def test_one_warning_hierarchy_under_the_old_names():
    assert nmea.DamagedRecordsWarning is DamagedRecordsWarning
    assert nav_damage.DamagedRecordsWarning is DamagedRecordsWarning
    assert nav_damage.DamageCounter is DamageCounter
    assert issubclass(LidarDataWarning, DamagedRecordsWarning)
    assert issubclass(SkippedRowsWarning, DamagedRecordsWarning)
    # A filter on the base class catches every reader's warning.
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DamagedRecordsWarning)
        warnings.warn("x", LidarDataWarning, stacklevel=1)
        warnings.warn("y", SkippedRowsWarning, stacklevel=1)


def test_counter_message_and_category():
    quiet = DamageCounter("log.txt")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        quiet.warn()  # nothing skipped: no warning
    counter = DamageCounter("rows.csv", what="bad row(s)", category=SkippedRowsWarning)
    for i in range(5):
        counter.add(f"line {i}")
    assert counter.count == 5 and counter.reasons == ["line 0", "line 1", "line 2"]

    def reader():  # the default stacklevel points at the reader's caller
        counter.warn()

    with pytest.warns(SkippedRowsWarning) as rec:
        reader()
    assert str(rec[0].message) == "rows.csv: skipped 5 bad row(s) (line 0; line 1; line 2; ...)"
    assert rec[0].filename == __file__
    two = DamageCounter("bag /imu")
    two.add("a")
    two.add("b")
    with pytest.warns(
        DamagedRecordsWarning, match=r"^bag /imu: skipped 2 damaged record\(s\) \(a; b\)$"
    ):
        two.warn(stacklevel=2)
