"""The Velodyne pcap reader as it was before it had its own record pass, rotation cutter and
decoder (`PeerPcapReader`): the pcap records walked in Python (`_iter_pcap_records`), UDP
payloads taken out by dpkt (`_udp_payload`), packets checked by numpy, every packet through one
velodyne-decoder `StreamDecoder`; a refusal of the last rotation is counted as damage, as every
other refusal (it raised RuntimeError before). `_iter_pcap_records` and `_udp_payload` are the
reader's code as it was, unchanged: the oracle of `_core.pcap_udp_datagrams`
(`test_pcap_records.py`), and `DpktPcapReader` is the reader with them (as it was before its
record pass moved to Rust). The peers of `test_pcap_reader.py`, `test_pcap_records.py` and
`benches/bench_pcap_reader.py`."""

from __future__ import annotations

import struct
from collections.abc import Iterator

import numpy as np
import velodyne_decoder as vd

from usvfast._extras import require
from usvfast.lidar.frame import LidarFrame
from usvfast.lidar.packets import (
    _BLOCK_FLAGS,
    _KNOWN_MODEL_IDS,
    _RETURN_MODES,
    VELODYNE_PACKET_SIZE,
    ReadStats,
    decoded_to_points,
    finish_read,
    velodyne_packet_problem,
)
from usvfast.lidar.pcap import VelodynePcapReader

# --- the reader's record and frame parsing as it was (moved here unchanged) ----------------

_PCAP_MAGICS = {
    b"\xd4\xc3\xb2\xa1": ("<", 1e-6),
    b"\xa1\xb2\xc3\xd4": (">", 1e-6),
    b"\x4d\x3c\xb2\xa1": ("<", 1e-9),
    b"\xa1\xb2\x3c\x4d": (">", 1e-9),
}


def _close_in_time(ref_sec: int, sec: int) -> bool:
    """True when `sec` can follow `ref_sec` in one capture stream (1 s of reordering back,
    up to a minute of silence forward)."""
    return -1 <= sec - ref_sec <= 60


def _iter_pcap_records(
    data: bytes, stats: ReadStats, source: str
) -> Iterator[tuple[float, int, bytes]]:
    """Yield (timestamp s, link type, frame bytes) of every readable pcap record.

    A record whose header is implausible (length beyond the snap length, a timestamp far
    from its neighbours) is counted as damaged and the stream resynchronises on the next
    position holding a plausible header followed by another plausible header (or the end
    of the file). A record cut by the end of the file is counted as damaged.

    A header's timestamp is judged by both neighbours, not by the last accepted record
    alone: a record whose seconds disagree with the previous record while the next record
    agrees with the previous one is the single outlier (a damaged `ts_sec`), so it is
    skipped and counted ("record timestamp") and the reference time stays; a jump that the
    next record confirms is a real clock step and is adopted (an unconfirmed jump, as in the
    last record, is damage).
    """
    if len(data) < 24 or data[:4] not in _PCAP_MAGICS:
        raise ValueError(f"{source}: not a libpcap file (pcapng is not supported)")
    endian, tick = _PCAP_MAGICS[data[:4]]
    snaplen, linktype = struct.unpack(endian + "II", data[16:24])
    snaplen = min(snaplen or 262144, 262144)
    hdr = struct.Struct(endian + "IIII")
    n = len(data)
    last_sec: int | None = None

    def plausible(pos: int, ref_sec: int | None) -> bool:
        if pos + 16 > n:
            return False
        sec, frac, incl, orig = hdr.unpack_from(data, pos)
        if incl == 0 or incl > snaplen or incl > orig or orig > 262144:
            return False
        if frac >= (1_000_000 if tick == 1e-6 else 1_000_000_000):
            return False
        return ref_sec is None or -3600 <= sec - ref_sec <= 86400

    def header_sec(pos: int) -> int | None:
        return hdr.unpack_from(data, pos)[0] if plausible(pos, None) else None

    def resync(start: int, ref_sec: int | None) -> int:
        pos = start
        while pos + 16 <= n:
            if plausible(pos, ref_sec):
                incl = hdr.unpack_from(data, pos)[2]
                nxt = pos + 16 + incl
                if nxt == n or plausible(nxt, ref_sec):
                    return pos
            pos += 1
        return n

    pos = 24
    while pos < n:
        if pos + 16 > n:
            stats.records += 1
            stats.damage("truncated record")
            return
        if not plausible(pos, last_sec):
            stats.records += 1
            stats.damage("record header")
            pos = resync(pos + 1, last_sec)
            continue
        sec, frac, incl, _ = hdr.unpack_from(data, pos)
        stats.records += 1
        if pos + 16 + incl > n:
            stats.damage("truncated record")
            return
        nxt = pos + 16 + incl
        next_sec = header_sec(nxt)
        if last_sec is None and next_sec is not None:
            # the first record: judged by the next two (is it or the next one the outlier?)
            after = header_sec(nxt + 16 + hdr.unpack_from(data, nxt)[2])
            judge = next_sec if after is None or _close_in_time(next_sec, after) else None
        else:
            judge = last_sec
        if judge is not None and not _close_in_time(judge, sec):
            if next_sec is None or _close_in_time(judge, next_sec):
                # the one outlier between agreeing neighbours (or a jump nothing confirms)
                stats.damage("record timestamp")
                pos = nxt
                continue
        last_sec = sec
        yield sec + frac * tick, linktype, data[pos + 16 : pos + 16 + incl]
        pos += 16 + incl


def _udp_payload(linktype: int, frame: bytes) -> tuple[int, bytes] | None:
    """(destination port, payload) of a UDP/IPv4 frame, None for anything else.

    Raises ValueError when the frame claims to be IPv4/UDP but its headers are broken
    (IP header checksum, lengths).
    """
    dpkt = require("dpkt", "lidar", "pcap files")

    try:
        if linktype == 1:
            eth = dpkt.ethernet.Ethernet(frame)
            ip = eth.data
        elif linktype in (101, 12):
            ip = dpkt.ip.IP(frame)
        elif linktype == 113:
            ip = dpkt.sll.SLL(frame).data
        else:
            return None
    except (dpkt.dpkt.UnpackError, struct.error) as exc:
        raise ValueError("link/IP header") from exc
    if not isinstance(ip, dpkt.ip.IP):
        return None
    # the header as stored (pack_hdr keeps the received checksum): sums to 0 when intact
    if dpkt.in_cksum(ip.pack_hdr() + bytes(ip.opts)) != 0:
        raise ValueError("IP checksum")
    udp = ip.data
    if not isinstance(udp, dpkt.udp.UDP):
        return None
    if udp.ulen != 8 + len(udp.data):
        raise ValueError("UDP length")
    return int(udp.dport), bytes(udp.data)


# --- the readers as they were --------------------------------------------------------------


class DpktPcapReader(VelodynePcapReader):
    """The reader as it was before its record pass and packet checks moved to Rust: records
    walked by `_iter_pcap_records`, payloads taken out by dpkt (`_udp_payload`), each packet
    checked by `check` (`velodyne_packet_problem`), its loop unchanged; the cutter and decoder
    are the reader's."""

    check = staticmethod(velodyne_packet_problem)

    def _data_packets(self, data, stats: ReadStats, source: str):
        # the counts are kept as the records are read: nothing to catch up with
        return self._checked_packets(data, stats, source), lambda packets: None

    def _checked_packets(
        self, data, stats: ReadStats, source: str
    ) -> Iterator[tuple[float, bytes]]:
        model_id: int | None = None
        for stamp, linktype, frame_bytes in _iter_pcap_records(data, stats, source):
            try:
                udp = _udp_payload(linktype, frame_bytes)
            except ValueError as exc:
                stats.damage(str(exc))
                continue
            if udp is None:
                continue
            port, payload = udp
            if self.data_port is not None and port != self.data_port:
                continue
            if len(payload) != VELODYNE_PACKET_SIZE:
                if self.data_port is not None:
                    stats.damage("packet length")
                continue  # position / telemetry packet
            problem = self.check(payload, model_id)
            if problem is not None:
                stats.damage(problem)
                continue
            model_id = payload[1205]
            yield stamp, payload


def packet_problem(payload: bytes, model_id: int | None = None) -> str | None:
    """Return why a 1206-byte Velodyne data packet is malformed, or None if it looks valid.

    Checks the block flags, the azimuths (< 36000 hundredths of a degree), the factory bytes
    (return mode, model id, and the model id against `model_id` when given).
    """
    if len(payload) != VELODYNE_PACKET_SIZE:
        return "packet length"
    blocks = np.frombuffer(payload, dtype="<u2", count=600).reshape(12, 50)
    flags = blocks[:, 0].tolist()  # 12 values: plain Python is faster than np.isin here
    if not all(f in _BLOCK_FLAGS for f in flags):
        return "block flag"
    if max(blocks[:, 1].tolist()) >= 36000:
        return "azimuth"
    return_mode, model = payload[1204], payload[1205]
    if return_mode not in _RETURN_MODES or model not in _KNOWN_MODEL_IDS:
        return "factory bytes"
    if model_id is not None and model != model_id:
        return "model id"
    return None


class PeerPcapReader(DpktPcapReader):
    """The pcap reader as it was before it had its own rotation cutter and decoder: the
    packets of `DpktPcapReader`'s record loop, checked with numpy (`packet_problem`), every one
    to one velodyne-decoder `StreamDecoder`, which cuts and decodes rotations."""

    check = staticmethod(packet_problem)

    def _frames(self, data) -> Iterator[LidarFrame]:
        self.stats = stats = ReadStats()
        source = str(self.path)
        decoder = vd.StreamDecoder(vd.Config(model=self.model))

        def emit(result: tuple) -> LidarFrame:
            stamp_pair, arr = result
            stamp = stamp_pair.device if self.device_time else stamp_pair.host
            frame = LidarFrame(
                float(stamp), decoded_to_points(arr), source=source, index=stats.frames
            )
            stats.frames += 1
            return frame

        for stamp, payload in self._checked_packets(data, stats, source):
            stats.packets += 1
            try:
                result = decoder.decode(stamp, payload)
            except RuntimeError:
                stats.damage("decoder")
                decoder = vd.StreamDecoder(vd.Config(model=self.model))
                continue
            if result is not None:
                yield emit(result)
        try:
            result = decoder.finish()
        except RuntimeError:  # counted, as the refusals above (the reader's damage policy)
            stats.damage("decoder")
            result = None
        if result is not None:
            yield emit(result)
        finish_read(stats, source)
