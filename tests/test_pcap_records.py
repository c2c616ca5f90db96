"""`_core.pcap_udp_datagrams` (the reader's record pass in Rust) against the reader's old
Python + dpkt path (`pcap_peer._iter_pcap_records` and `pcap_peer._udp_payload`, unchanged):
the same records counted, the same datagrams (stamps bit for bit, ports, payload bytes) and
the same damage under the same labels, on the real HDL-32E capture, simulated captures, every
link type, both resolutions and byte orders, and hypothesis-made damaged streams.

Where dpkt itself fails with an exception the reader never caught (an MPLS label stack with
nothing after it raises IndexError, in Ethernet's first payload pass or its second; the old
reader stopped there), the Rust pass reads the frame as if that exception were dpkt's
`UnpackError`: `dpkt_as_if_unpack_error` gives the oracle for those frames, and the tests
count them.
"""

from __future__ import annotations

import contextlib
import struct
from collections import Counter

import dpkt
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pcap_peer import _iter_pcap_records, _udp_payload

from usvfast._core import pcap_udp_datagrams
from usvfast.lidar.packets import ReadStats
from usvfast.sim.velodyne import udp_frame, write_velodyne_pcap

from conftest import SHARED_DATA

PCAP = SHARED_DATA / "lidar" / "velodyne_hdl32e.pcap"
FRAME_LABELS = {"link/IP header", "IP checksum", "UDP length"}
T0 = 1_415_644_617  # the real capture's second, UNIX s


class DpktCrash(Exception):
    """dpkt raised something the reader did not catch (the old reader stopped)."""


def frame_result(linktype: int, frame: bytes):
    """The old path's reading of one frame: (port, payload), None, or a damage label."""
    try:
        return _udp_payload(linktype, frame)
    except ValueError as exc:
        if str(exc) in FRAME_LABELS:
            return str(exc)
        raise DpktCrash(repr(exc)) from exc
    except Exception as exc:  # what the reader let through
        raise DpktCrash(repr(exc)) from exc


@contextlib.contextmanager
def dpkt_as_if_unpack_error():
    """Every dpkt parser's `unpack` (and Ethernet's payload pass `_unpack_data`, which its
    constructor runs a second time) raises `UnpackError` where it raised anything else."""
    saved = []

    def classes(cls):
        for sub in cls.__subclasses__():
            yield sub
            yield from classes(sub)

    def wrap(method):
        def guarded(self, buf):
            try:
                return method(self, buf)
            except (dpkt.UnpackError, struct.error):
                raise
            except Exception as exc:
                raise dpkt.UnpackError(repr(exc)) from exc

        return guarded

    for cls in set(classes(dpkt.Packet)):
        for name in ("unpack", "_unpack_data"):
            if name in vars(cls):
                saved.append((cls, name, vars(cls)[name]))
                setattr(cls, name, wrap(vars(cls)[name]))
    try:
        yield
    finally:
        for cls, name, method in saved:
            setattr(cls, name, method)


class LoggedStats(ReadStats):
    """ReadStats that also logs each damage with the number of datagrams read before it."""

    def __init__(self, datagrams: list) -> None:
        super().__init__()
        self.datagrams, self.log = datagrams, []

    def damage(self, reason: str, count: int = 1) -> None:
        super().damage(reason, count)
        self.log += [(len(self.datagrams), reason)] * count


def oracle(data: bytes) -> tuple[list, int, list, int]:
    """(datagrams [(stamp, port, payload, records seen up to its record)], records, damage
    [(datagrams before it, label)], frames dpkt failed on) of the old path; raises ValueError
    as it did."""
    out, crashes = [], 0
    stats = LoggedStats(out)
    for stamp, linktype, frame in _iter_pcap_records(data, stats, "x"):
        try:
            got = frame_result(linktype, frame)
        except DpktCrash:
            crashes += 1
            with dpkt_as_if_unpack_error():
                got = frame_result(linktype, frame)
        if isinstance(got, str):
            stats.damage(got)
        elif got is not None:
            out.append((stamp, got[0], got[1], stats.records))
    return out, stats.records, stats.log, crashes


def ours(data) -> tuple[list, int, list]:
    """The Rust pass's reading of `data` (bytes or a uint8 array), in the oracle's terms."""
    found = pcap_udp_datagrams(data)
    assert sorted(found) == sorted(
        ["times", "ports", "offsets", "lengths", "record_counts", "records", "damage"]
    )
    times, ports, offsets, lengths, counts = (
        found[k] for k in ("times", "ports", "offsets", "lengths", "record_counts")
    )
    assert times.dtype == np.float64 and ports.dtype == np.uint16
    assert offsets.dtype == lengths.dtype == counts.dtype == np.int64
    buf = bytes(data)
    rows = zip(*(a.tolist() for a in (times, ports, offsets, lengths, counts)), strict=True)
    out = [(t, p, buf[o : o + n], c) for t, p, o, n, c in rows]
    return out, found["records"], found["damage"]


def assert_same(data: bytes) -> tuple[list, int, list, int]:
    """Ours equals the old path on `data` (both refuse it alike): the same datagrams (stamps,
    ports, payloads, records seen up to each), records and damage, each damage after the same
    datagrams; returns the oracle's reading."""
    try:
        ref = oracle(data)
    except ValueError as exc:
        assert "not a libpcap file (pcapng is not supported)" in str(exc)
        with pytest.raises(ValueError, match=r"^data: not a libpcap file \(pcapng"):
            pcap_udp_datagrams(data)
        return [], 0, [], 0
    got = ours(data)
    assert got[1] == ref[1], "records"
    assert got[2] == ref[2], "damage"
    assert len(got[0]) == len(ref[0])
    for a, b in zip(got[0], ref[0], strict=True):
        assert a == b
    # a uint8 view (as the reader passes its mmap) reads the same
    assert ours(np.frombuffer(data, dtype=np.uint8)) == got
    return ref


# --- capture writing ----------------------------------------------------------------------


def pcap_bytes(
    records: list[tuple[int, int, bytes]],
    *,
    linktype: int = 1,
    big: bool = False,
    nanos: bool = False,
    snaplen: int = 65535,
) -> bytes:
    """A libpcap file of (seconds, fraction in µs or ns, frame) records."""
    end = ">" if big else "<"
    magic = 0xA1B23C4D if nanos else 0xA1B2C3D4
    out = [struct.pack(end + "IHHiIII", magic, 2, 4, 0, 0, snaplen, linktype)]
    for sec, frac, frame in records:
        out.append(struct.pack(end + "IIII", sec, frac, len(frame), len(frame)) + frame)
    return b"".join(out)


def checksum(header: bytes) -> int:
    """RFC 1071 one's complement sum, complemented."""
    if len(header) % 2:
        header += b"\0"
    s = sum(struct.unpack(f">{len(header) // 2}H", header))
    while s > 0xFFFF:
        s = (s >> 16) + (s & 0xFFFF)
    return ~s & 0xFFFF


def ipv4(
    payload: bytes, *, proto=17, words=5, frag=0x4000, total=None, ulen=None, port=2368, version=4
):
    """An IPv4 packet around a UDP datagram (or `payload` alone when proto is not 17), options
    `words - 5` words of filler, checksum filled in."""
    body = payload
    if proto == 17:
        n = 8 + len(payload) if ulen is None else ulen
        body = struct.pack(">HHHH", 2368, port, n, 0) + payload
    opts = bytes(range(1, 4 * words - 19))
    n = 4 * words + len(body) if total is None else total
    head = struct.pack(
        ">BBHHHBBH4s4s",
        version << 4 | words,
        0,
        n,
        7,
        frag,
        64,
        proto,
        0,
        b"\xc0\xa8\x01\xc9",
        b"\xff" * 4,
    )
    head += opts
    head = head[:10] + struct.pack(">H", checksum(head)) + head[12:]
    return head + body


def ether(ethertype: int, body: bytes, dst: bytes = b"\xff" * 6) -> bytes:
    return dst + bytes.fromhex("60768800a1b2") + struct.pack(">H", ethertype) + body


def sll(ethertype: int, body: bytes) -> bytes:
    return struct.pack(">HHH8sH", 4, 1, 6, b"\x60\x76\x88\x00\xa1\xb2\0\0", ethertype) + body


# --- the real capture and simulated ones ---------------------------------------------------


def test_real_capture():
    data = PCAP.read_bytes()
    found, records, damage, crashes = assert_same(data)
    assert (len(found), records, damage, crashes) == (100, 100, [], 0)
    assert Counter(p for _, p, _, _ in found) == {2368: 84, 8308: 16}
    assert {len(b) for _, p, b, _ in found if p == 2368} == {1206}


@pytest.mark.parametrize("cut", [24, 40, 1000, 60_000, 61_300, 115_000])
def test_real_capture_cut(cut):
    assert_same(PCAP.read_bytes()[:cut])


@settings(max_examples=200)
@given(
    edits=st.lists(st.tuples(st.integers(24, 115_319), st.integers(0, 255)), min_size=1, max_size=8)
)
def test_real_capture_byte_flipped(edits):
    data = bytearray(PCAP.read_bytes())
    for at, value in edits:
        data[at] = value
    assert_same(bytes(data))


def test_real_capture_in_every_format():
    """The real capture's records rewritten in each byte order and resolution, then each
    frame as raw IP (101, 12) and Linux SLL (113): the same payloads and stamps."""
    data, recs, pos = PCAP.read_bytes(), [], 24  # a clean capture: record after record
    while pos < len(data):
        sec, usec, incl, _ = struct.unpack_from("<IIII", data, pos)
        recs.append((sec, usec, data[pos + 16 : pos + 16 + incl]))
        pos += 16 + incl
    base = ours(PCAP.read_bytes())[0]
    for big in (False, True):
        for nanos in (False, True):
            rows = [(s, u * 1000 + 999 if nanos else u, f) for s, u, f in recs]
            for linktype, wrap in [
                (1, bytes),
                (101, lambda f: f[14:]),
                (12, lambda f: f[14:]),
                (113, lambda f: sll(0x0800, f[14:])),
            ]:
                data = pcap_bytes(
                    [(s, u, wrap(f)) for s, u, f in rows], linktype=linktype, big=big, nanos=nanos
                )
                found = assert_same(data)[0]
                assert [(p, b) for _, p, b, _ in found] == [(p, b) for _, p, b, _ in base]
                tick = 1e-9 if nanos else 1e-6
                assert [t for t, _, _, _ in found] == [s + u * tick for s, u, _ in rows]
    # an unknown link type holds no datagram
    assert assert_same(pcap_bytes(recs, linktype=228))[:2] == ([], 100)


def test_simulated_capture(tmp_path):
    rng = np.random.default_rng(5)
    packets = rng.integers(0, 256, (300, 1206), dtype=np.uint8)
    times = 1_686_909_600.0123 + np.cumsum(rng.uniform(0, 2e-3, 300))
    path = tmp_path / "sim.pcap"
    write_velodyne_pcap(path, packets, times, port=2369)
    found = assert_same(path.read_bytes())[0]
    assert [b for _, _, b, _ in found] == [p.tobytes() for p in packets]
    assert {p for _, p, _, _ in found} == {2369}


def test_frames_of_the_simulator_in_every_shape():
    """The simulator's frames (`udp_frame`) with payloads from empty to a full MTU and ports at
    the edges."""
    frames = [
        udp_frame(bytes([k]) * n, port, k)
        for k, (n, port) in enumerate(
            [(0, 1), (1, 2368), (7, 8308), (512, 65535), (1206, 2368), (1472, 0)]
        )
    ]
    data = pcap_bytes([(T0, 10 * k, f) for k, f in enumerate(frames)])
    found = assert_same(data)[0]
    assert [len(b) for _, _, b, _ in found] == [0, 1, 7, 512, 1206, 1472]


# --- link layers, IPv4 and UDP headers, one case at a time ---------------------------------

UDP = ipv4(b"velodyne")
VLAN = struct.pack(">HH", 5, 0x0800) + UDP
FRAMES = {
    "ethernet": (1, ether(0x0800, UDP)),
    "ethernet padded": (1, ether(0x0800, UDP) + b"\0" * 6),
    "802.1Q": (1, ether(0x8100, VLAN)),
    "QinQ 802.1ad": (1, ether(0x88A8, struct.pack(">HH", 6, 0x8100) + VLAN)),
    "QinQ 0x9100 single": (1, ether(0x9100, VLAN)),
    "three tags": (
        1,
        ether(0x8100, struct.pack(">HH", 7, 0x8100) + struct.pack(">HH", 6, 0x8100) + VLAN),
    ),
    "five tags": (
        1,
        ether(0x8100, struct.pack(">HH", 8, 0x8100) * 3 + struct.pack(">HH", 6, 0x8100) + VLAN),
    ),
    "tag naming MPLS": (1, ether(0x8100, struct.pack(">HH", 5, 0x8847) + b"\0\1\1\x40" + UDP)),
    "tag naming MPLS, cut": (1, ether(0x8100, struct.pack(">HH", 5, 0x8847) + b"\0\1")),
    "tag naming 802.1ad": (1, ether(0x8100, struct.pack(">HH", 5, 0x88A8) + VLAN)),
    "tag type 0": (1, ether(0x8100, struct.pack(">HH", 5, 0) + UDP)),
    "tag cut": (1, ether(0x8100, b"\0\1\x08")),
    "MPLS": (1, ether(0x8847, b"\0\1\1\x40" + UDP)),
    "MPLS two labels": (1, ether(0x8848, b"\0\1\0\x40\0\2\1\x40" + UDP)),
    "MPLS no bottom": (1, ether(0x8847, b"\0\1\0\x40" * 24 + UDP)),
    "MPLS IPv6": (1, ether(0x8847, b"\0\1\1\x40" + b"\x60" + UDP[1:])),
    "MPLS pseudowire": (1, ether(0x8847, b"\0\1\1\x40" + b"\0\0\0\0" + ether(0x0800, UDP))),
    "MPLS cut label": (1, ether(0x8847, b"\0\1\0")),
    "MPLS empty": (1, ether(0x8847, b"\0\1\1\x40")),
    "ISL": (1, b"\x01\x00\x0c\x00\x00" + bytes(21) + ether(0x0800, UDP)),
    "ISL twice": (1, (b"\x03\x00\x0c\x00\x00" + bytes(21)) * 2 + ether(0x8100, VLAN)),
    "ISL cut": (1, b"\x01\x00\x0c\x00\x00" + bytes(21) + bytes(10)),
    "ISL short": (1, b"\x01\x00\x0c\x00\x00" + bytes(15)),
    "Novell raw": (1, ether(40, b"\xff" * 32)),
    "Novell raw cut": (1, ether(40, b"\xff" * 31)),
    "LLC SNAP": (1, ether(50, b"\xaa\xaa\x03\0\0\0\x08\x00" + UDP)),
    "LLC SNAP cut": (1, ether(6, b"\xaa\xaa\x03\0\0\0\x08\x00" + UDP)),
    "LLC cut": (1, ether(2, UDP)),
    "LLC IP": (1, ether(3 + len(UDP), b"\x06\x06\x03" + UDP)),
    "LLC IP cut": (1, ether(22, b"\x06\x06\x03" + UDP)),
    "LLC IPX cut": (1, ether(30, b"\xe0\xe0\x03" + bytes(40))),
    "LLC STP": (1, ether(38, b"\x42\x42\x03" + bytes(40))),
    "LLC STP cut": (1, ether(37, b"\x42\x42\x03" + bytes(40))),
    "type 0": (1, ether(0, UDP)),
    "ARP": (1, ether(0x0806, bytes(28))),
    "IPv6 UDP": (
        1,
        ether(
            0x86DD, struct.pack(">IHBB16s16s", 6 << 28, 16, 17, 64, bytes(16), bytes(16)) + UDP[20:]
        ),
    ),
    "TEB": (1, ether(0x6558, ether(0x0800, UDP))),
    "PPPoE": (1, ether(0x8864, struct.pack(">BBHH", 0x11, 0, 1, len(UDP) + 2) + b"\x00\x21" + UDP)),
    "ethernet cut": (1, ether(0x0800, UDP)[:13]),
    "IPv4 cut": (1, ether(0x0800, UDP[:19])),
    "IPv4 header length 4": (1, ether(0x0800, b"\x44" + UDP[1:])),
    "options": (1, ether(0x0800, ipv4(b"opt", words=8))),
    "options 15 words": (1, ether(0x0800, ipv4(b"o", words=15))),
    "options cut": (1, ether(0x0800, ipv4(b"o", words=15)[:50])),
    "TCP": (1, ether(0x0800, ipv4(bytes(20), proto=6))),
    "ICMP": (1, ether(0x0800, ipv4(bytes(8), proto=1))),
    "IP in IP": (1, ether(0x0800, ipv4(UDP, proto=4))),
    "first fragment": (1, ether(0x0800, ipv4(b"frag", frag=0x2000))),
    "first fragment, UDP length of the whole": (
        1,
        ether(0x0800, ipv4(b"frag", frag=0x2000, ulen=3000)),
    ),
    "later fragment": (1, ether(0x0800, ipv4(b"frag", frag=0x2001))),
    "total length 0": (1, ether(0x0800, ipv4(b"tso", total=0))),
    "total length short": (1, ether(0x0800, ipv4(b"payload", total=30))),
    "total length in the header": (1, ether(0x0800, ipv4(b"payload", total=10))),
    "total length long": (1, ether(0x0800, ipv4(b"payload", total=400))),
    "UDP header cut": (1, ether(0x0800, ipv4(b"", total=24)[:24])),
    "UDP length long": (1, ether(0x0800, ipv4(b"abc", ulen=12))),
    "UDP length short": (1, ether(0x0800, ipv4(b"abc", ulen=8))),
    "IP checksum": (1, ether(0x0800, UDP[:10] + b"\0\0" + UDP[12:])),
    "version 6 nibble": (1, ether(0x0800, ipv4(b"velodyne", version=6))),
    "version 6 nibble, its checksum": (1, ether(0x0800, b"\x65" + UDP[1:])),
    "raw": (101, UDP),
    "raw 12": (12, UDP),
    "raw cut": (101, UDP[:19]),
    "raw IPv6": (101, b"\x60" + UDP[1:]),
    "SLL": (113, sll(0x0800, UDP)),
    "SLL IPv6": (113, sll(0x86DD, UDP)),
    "SLL VLAN": (113, sll(0x8100, VLAN)),
    "SLL IPv4 cut": (113, sll(0x0800, UDP[:12])),
    "SLL cut": (113, sll(0x0800, b"")[:15]),
    "null link type": (0, b"\x02\0\0\0" + UDP),
}


@pytest.mark.parametrize("name", sorted(FRAMES))
def test_one_frame(name):
    linktype, frame = FRAMES[name]
    data = pcap_bytes([(T0, 0, frame)], linktype=linktype)
    found, records, _, crashes = assert_same(data)
    assert records == 1
    assert crashes == (name == "MPLS empty")
    if name in CARRY_THE_PAYLOAD:
        assert [(p, b) for _, p, b, _ in found] == [(2368, b"velodyne")]


#: The frames above that dpkt (and the Rust pass) read to the datagram `UDP`.
CARRY_THE_PAYLOAD = {
    "ethernet",
    "ethernet padded",
    "802.1Q",
    "QinQ 802.1ad",
    "QinQ 0x9100 single",
    "MPLS",
    "MPLS two labels",
    "MPLS no bottom",
    "ISL",
    "version 6 nibble",
    "three tags",
    "ISL twice",
    "tag naming MPLS",
    "tag naming 802.1ad",
    "raw",
    "raw 12",
    "SLL",
}


def test_which_frames_carry_a_datagram():
    """dpkt's acceptance, spelled out: VLAN/QinQ tags (up to four: dpkt decodes a payload it
    left as bytes a second time), MPLS and ISL lead to the datagram, as does an IPv4 header
    with a version nibble of 6; IPv6, LLC/SNAP, SLL with VLAN, pseudowires, later fragments
    and other link types do not."""
    carry = set()
    for name, (linktype, frame) in FRAMES.items():
        found = ours(pcap_bytes([(T0, 0, frame)], linktype=linktype))[0]
        if [(p, b) for _, p, b, _ in found] == [(2368, b"velodyne")]:
            carry.add(name)
    assert carry == CARRY_THE_PAYLOAD


def test_dpkt_fails_on_a_bare_label_stack_where_the_rust_pass_counts_damage():
    """The one frame kind where dpkt raises what the reader never caught (IndexError): the
    Rust pass counts it as "link/IP header" damage and reads on."""
    with pytest.raises(IndexError):
        _udp_payload(1, FRAMES["MPLS empty"][1])
    data = pcap_bytes([(T0, 0, FRAMES["MPLS empty"][1]), (T0, 1, FRAMES["ethernet"][1])])
    found, records, damage = ours(data)
    assert (len(found), records, damage) == (1, 2, [(0, "link/IP header")])


# --- hypothesis: damaged streams ------------------------------------------------------------


def rare(draw, common, *rare_values, one_in: int = 8):
    """`common` drawn, or one of `rare_values` once in `one_in` draws."""
    if rare_values and draw(st.integers(0, one_in - 1)) == 0:
        return draw(st.sampled_from(rare_values))
    return draw(common)


@st.composite
def frames(draw, linktype: int) -> bytes:
    """A frame of `linktype`: mostly a UDP/IPv4 datagram in some shape (tags, labels, ISL,
    padding, options, fragments, odd lengths), else another protocol, one of `FRAMES`, or
    garbage."""
    kind = rare(draw, st.just("udp"), "other", "garbage", "named", one_in=3)
    if kind == "named":
        lt, frame = FRAMES[draw(st.sampled_from(sorted(FRAMES)))]
        return frame if lt == linktype else frame[draw(st.integers(0, 20)) :]
    if kind == "garbage":
        return draw(st.binary(min_size=1, max_size=80))
    size = draw(st.sampled_from([0, 1, 8, 512, 1206]))
    ip = ipv4(
        bytes([size % 251]) * size,
        proto=17 if kind == "udp" else draw(st.sampled_from([1, 4, 6, 41, 47, 50, 89, 132])),
        words=rare(draw, st.just(5), 6, 15, 4),
        frag=rare(draw, st.just(0x4000), 0, 0x2000, 0x0001),
        total=rare(draw, st.none(), 0, 12, 400),
        ulen=rare(draw, st.none(), 8, 9),
        port=draw(st.sampled_from([2368, 8308, 9])),
    )
    if linktype in (101, 12):
        return ip
    ethertype = rare(draw, st.just(0x0800), 0x86DD, 0x0806, 0x8100, 0x8847)
    if linktype == 113:
        return sll(ethertype, ip)
    wrap = rare(draw, st.just("none"), "vlan", "qinq", "mpls", "isl", "pad", one_in=2)
    if wrap == "vlan":
        return ether(0x8100, struct.pack(">HH", 5, ethertype) + ip)
    if wrap == "qinq":
        return ether(0x88A8, struct.pack(">HHHH", 6, 0x8100, 5, ethertype) + ip)
    if wrap == "mpls":
        return ether(0x8847, b"\0\1\1\x40" + ip)
    if wrap == "isl":
        return b"\x01\x00\x0c\x00\x00" + bytes(21) + ether(ethertype, ip)
    if wrap == "pad":
        return ether(ethertype, ip) + bytes(draw(st.integers(1, 30)))
    return ether(ethertype, ip)


@st.composite
def captures(draw) -> bytes:
    """A capture of some link type, byte order and resolution whose clock runs on with
    jitter, reordering, real steps and single outliers; then record headers, frame headers and
    bytes anywhere edited, garbage (now and then holding a copied record header) put between
    records, the end cut."""
    linktype = draw(st.sampled_from([1, 1, 1, 101, 12, 113, 228]))
    big, nanos = draw(st.booleans()), draw(st.booleans())
    per_second = 1_000_000_000 if nanos else 1_000_000
    sec, records = T0 + draw(st.integers(-3, 3)), []
    for _ in range(draw(st.integers(1, 16))):
        # reordering, silences, clock steps (those past an hour back or a day on: implausible)
        sec += rare(draw, st.sampled_from([0, 0, 1]), -1, -2, 61, 3600)
        sec += rare(draw, st.just(0), 90_000, -4000, one_in=40)
        # a lone outlier: this record's seconds only
        stamp = sec + rare(draw, st.just(0), -1_000_000, -3601, -61, 61, 3599, 86_399, 86_401)
        frac = rare(draw, st.integers(0, per_second - 1), per_second, 2**32 - 1, one_in=16)
        records.append((stamp % 2**32, frac, draw(frames(linktype))))
    snaplen = rare(draw, st.just(65535), 0, 1600, 300, 2**31, one_in=4)
    data = bytearray(pcap_bytes(records, linktype=linktype, big=big, nanos=nanos, snaplen=snaplen))
    starts, pos = [], 24
    for _, _, frame in records:
        starts.append(pos)
        pos += 16 + len(frame)
    # record header fields, Ethernet type, IP header (length, flags, protocol, checksum), UDP
    # length, or anywhere in the first 100 bytes of a record
    spots = [0, 3, 4, 7, 8, 9, 11, 12, 15, 28, 29, 30, 32, 33, 36, 37, 39, 40, 54, 55]
    for _ in range(draw(st.sampled_from([0, 0, 1, 2, 4])) if starts else 0):
        at = draw(st.sampled_from(starts)) + rare(
            draw, st.sampled_from(spots), *range(100), one_in=3
        )
        if at < len(data):
            data[at] = draw(st.integers(0, 255))
    if starts and draw(st.integers(0, 2)) == 0:
        at = draw(st.sampled_from([*starts, len(data)]))
        garbage = draw(st.binary(min_size=1, max_size=40))
        if draw(st.booleans()):  # a plausible header in the garbage, pointing anywhere
            copy = draw(st.sampled_from(starts))
            garbage = garbage[: draw(st.integers(0, 8))] + bytes(data[copy : copy + 16]) + garbage
        data[at:at] = garbage
    if draw(st.integers(0, 2)) == 0:
        data = data[: draw(st.integers(24, len(data)))]
    return bytes(data)


@settings(max_examples=400)
@given(data=captures())
def test_damaged_streams(data):
    assert_same(data)


@settings(max_examples=100)
@given(
    garbage=st.binary(min_size=0, max_size=300),
    head=st.sampled_from([b"\xd4\xc3\xb2\xa1", b"\xa1\xb2\x3c\x4d", b"\x0a\x0d\x0d\x0a", b""]),
)
def test_garbage_files(garbage, head):
    assert_same(head + garbage)


# --- the binding's arguments --------------------------------------------------------------


def test_bad_data_names_the_argument():
    for bad in (None, 3, "pcap", [1, 2], np.zeros(30), np.zeros((3, 24), np.uint8), bytearray(30)):
        with pytest.raises(TypeError, match=r"^data: expected bytes or a 1-D uint8 array"):
            pcap_udp_datagrams(bad)
    with pytest.raises(ValueError, match=r"^data: must be a C-contiguous array"):
        pcap_udp_datagrams(np.frombuffer(PCAP.read_bytes(), np.uint8)[::2])
    for bad in (b"", b"\xd4\xc3\xb2\xa1" * 5, b"\x0a\x0d\x0d\x0a" + bytes(40)):
        with pytest.raises(
            ValueError, match=r"^data: not a libpcap file \(pcapng is not supported\)$"
        ):
            pcap_udp_datagrams(bad)
