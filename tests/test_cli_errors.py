"""The CLI for users: `--version`, one-line errors with exit status 2, a missing extra named."""

from __future__ import annotations

import sys

import pytest

from usvfast import __version__, cli
from usvfast._extras import MissingExtraError
from usvfast.lidar import VelodynePcapReader

from conftest import SHARED_DATA

PCAP = SHARED_DATA / "lidar" / "velodyne_hdl32e.pcap"


def run(monkeypatch, capsys, *args):
    monkeypatch.setattr(sys, "argv", ["usvfast", *args])
    with pytest.raises(SystemExit) as info:
        cli.main()
    out = capsys.readouterr()
    return info.value.code, out.out, out.err


def test_version(monkeypatch, capsys):
    code, out, _ = run(monkeypatch, capsys, "--version")
    assert code == 0 and out.strip() == __version__


def test_user_error_is_one_line_and_exit_2(monkeypatch, capsys, tmp_path):
    code, _, err = run(monkeypatch, capsys, "lidar", str(tmp_path / "missing.pcap"))
    assert code == 2
    assert err.startswith("usvfast: error: ") and err.count("\n") == 1
    assert "Traceback" not in err


def test_missing_extra_names_what_to_install(monkeypatch, capsys, tmp_path):
    # VLP-16 and HDL-32E packets are decoded by usvfast itself; a VLP-32C's by velodyne-decoder
    import dpkt

    vlp32c = tmp_path / "vlp32c.pcap"
    with PCAP.open("rb") as src, vlp32c.open("wb") as dst:
        writer = dpkt.pcap.Writer(dst)
        for ts, buf in dpkt.pcap.Reader(src):
            if len(buf) == 42 + 1206:
                buf = buf[:-1] + b"\x28"  # the model id byte
            writer.writepkt(buf, ts=ts)
    assert len(list(VelodynePcapReader(PCAP))) == 2
    monkeypatch.setitem(sys.modules, "velodyne_decoder", None)  # as if not installed
    assert len(list(VelodynePcapReader(PCAP))) == 2
    with pytest.raises(MissingExtraError, match=r"install usvfast\[lidar\] for"):
        list(VelodynePcapReader(vlp32c))
    code, _, err = run(monkeypatch, capsys, "lidar", str(vlp32c))
    assert code == 2 and "install usvfast[lidar]" in err and err.count("\n") == 1


def test_the_cli_imports_without_any_optional_extra():
    # `make demo` installs no test tools, no torch and no cluster extra: the CLI must load.
    import subprocess
    import sys

    # (torch is left alone: scipy probes sys.modules["torch"] itself; the demo venv has none.)
    blocked = ("pandas", "distributed", "pyarrow", "stonesoup", "plotly", "trackeval")
    code = (
        "import sys\n"
        f"for m in {blocked!r}: sys.modules[m] = None\n"
        "import usvfast.cli\n"
        "print('ok')\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=False)
    assert out.returncode == 0 and out.stdout.strip() == "ok", out.stderr
