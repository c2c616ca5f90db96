"""Velodyne `.pcap` captures (`VelodynePcapReader`), one frame per rotation. The record
stream resynchronises on the next plausible record header after a damaged record; damaged
records are skipped and counted (`usvfast.lidar.packets`). The packets are cut into rotations
(`RotationCutter`) where velodyne-decoder's `StreamDecoder` cuts them and decoded by
`VelodyneScanDecoder`: the frames are the ones velodyne-decoder gives, bit for bit."""

from __future__ import annotations

import mmap
import os
import struct
from collections.abc import Iterator
from pathlib import Path

from usvfast._extras import require
from usvfast._files import regular_file
from usvfast._validate import integer
from usvfast.lidar.frame import LidarFrame
from usvfast.lidar.packets import (
    VELODYNE_PACKET_SIZE,
    ReadStats,
    VelodyneScanDecoder,
    decoded_to_points,
    finish_read,
    velodyne_packet_problem,
)

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


#: Byte offset of the last block's azimuth in a data packet (block 11, after its flag).
_LAST_AZIMUTH_AT = 11 * 100 + 2
#: A rotation spanning more host time than this, s, ends before the packet that exceeds it
#: (a rotation takes 0.2 s at the slowest spin, 300 rpm).
_MAX_ROTATION_S = 0.3


class RotationCutter:
    """Cuts a stream of Velodyne data packets into rotations exactly where velodyne-decoder's
    `StreamDecoder` (default `Config`: no cut angle, stamped by the last packet) cuts it.

    A rotation's coverage is the azimuth of each packet's last block past the rotation's
    start azimuth (0.01° units, modulo a turn). The start azimuth is that of the previous
    rotation's last packet (of the first packet for the stream's first rotation). A packet
    whose coverage is smaller than the coverage before it, once that passed half a turn,
    ends the rotation and belongs to it. A packet more than `_MAX_ROTATION_S` of host time
    after the rotation's first packet ends the rotation before it, and starts the next one.
    `finish` gives what is left.

    Packets must have passed `velodyne_packet_problem` (azimuths below 36000). The cutter
    keeps plain lists; `push` is a few integer operations per packet.
    """

    def __init__(self) -> None:
        self.reset()

    def reset(self) -> None:
        """Forget everything: the next packet starts the first rotation of a new stream."""
        self._payloads: list[bytes] = []
        self._times: list[float] = []
        self._start = -1  # start azimuth of the rotation, 0.01°; -1 before the first packet
        self._last = -1  # azimuth of the last packet pushed
        self._coverage = 0

    def push(self, payload: bytes, host_time: float) -> tuple[list[bytes], list[float]] | None:
        """Add one packet (1206-byte payload, host time UNIX s); returns the (payloads, host
        times) of the rotation this packet completes, or None."""
        azimuth = payload[_LAST_AZIMUTH_AT] | payload[_LAST_AZIMUTH_AT + 1] << 8
        if self._start < 0:
            self._start = azimuth
        if self._payloads and host_time - self._times[0] > _MAX_ROTATION_S:
            done = (self._payloads, self._times)
            self._start = self._last
            self._payloads, self._times = [payload], [host_time]
            self._coverage = (azimuth - self._start) % 36000
            self._last = azimuth
            return done
        self._payloads.append(payload)
        self._times.append(host_time)
        coverage = (azimuth - self._start) % 36000
        complete = self._coverage > 18000 and self._coverage > coverage
        self._coverage = coverage
        self._last = azimuth
        if not complete:
            return None
        done = (self._payloads, self._times)
        self._payloads, self._times = [], []
        self._start, self._coverage = azimuth, 0
        return done

    def finish(self) -> tuple[list[bytes], list[float]] | None:
        """The (payloads, host times) of the unfinished rotation, or None when it is empty;
        the cutter is empty afterwards."""
        if not self._payloads:
            return None
        done = (self._payloads, self._times)
        self._payloads, self._times = [], []
        return done


class VelodynePcapReader:
    """Stream the rotations of a Velodyne `.pcap` capture (libpcap format).

    Parameters
    ----------
    path : path of the capture.
    model : velodyne_decoder.Model or None
        Sensor model; None takes it from the first rotation (as velodyne-decoder does). A
        rotation the decoder refuses (another model) is counted as "decoder" damage and the
        stream starts again after it.
    data_port : int or None
        UDP destination port of data packets; None accepts any port (position/telemetry
        packets are recognised by their size and ignored).
    device_time : bool
        Stamp frames with the sensor's own clock (top-of-hour packet stamps, only right
        when the sensor is GPS-synchronised) instead of the capture host's clock (default).

    every : int
        Yield only every `every`-th rotation (the rotations are cut from the packet stream, so
        all are read; those left out are decoded only where velodyne-decoder decodes them).

    Iterating yields `LidarFrame`s; `stats` counts records, packets, frames and damage.
    Raises ValueError at the end of iteration if no frame could be decoded.
    """

    def __init__(
        self,
        path: str | Path,
        *,
        model: object | None = None,
        data_port: int | None = None,
        device_time: bool = False,
        every: int = 1,
    ) -> None:
        self.path = Path(path)
        self.model = model
        self.data_port = data_port
        self.device_time = device_time
        self.every = integer("every", every, low=1)
        self.stats = ReadStats()

    def __iter__(self) -> Iterator[LidarFrame]:
        with regular_file(self.path, "path").open("rb") as fh:
            size = os.fstat(fh.fileno()).st_size
            # memory-mapped: captures of several GB are streamed, not loaded
            data = mmap.mmap(fh.fileno(), 0, access=mmap.ACCESS_READ) if size else b""
            try:
                for frame in self._frames(data):
                    if frame.index % self.every == 0:
                        yield frame
            finally:
                if isinstance(data, mmap.mmap):
                    data.close()

    def _frames(self, data) -> Iterator[LidarFrame]:
        self.stats = stats = ReadStats()
        source = str(self.path)
        decoder = VelodyneScanDecoder(self.model)
        cutter = RotationCutter()
        model_id: int | None = None

        def decode(rotation: tuple[list[bytes], list[float]]) -> LidarFrame | None:
            """The rotation's frame; None when `every` leaves it out, or when the decoder
            refuses it (counted as "decoder" damage, the stream starts again from the next
            packet)."""
            nonlocal decoder
            try:
                if stats.frames % self.every and decoder.skip(rotation[0]):
                    stats.frames += 1  # a rotation `every` leaves out: not decoded
                    return None
                (host, device), arr = decoder.decode(*rotation)
            except RuntimeError:
                stats.damage("decoder")
                decoder = VelodyneScanDecoder(self.model)
                cutter.reset()
                return None
            stamp = device if self.device_time else host
            frame = LidarFrame(
                float(stamp), decoded_to_points(arr), source=source, index=stats.frames
            )
            stats.frames += 1
            return frame

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
            problem = velodyne_packet_problem(payload, model_id)
            if problem is not None:
                stats.damage(problem)
                continue
            model_id = payload[1205]
            stats.packets += 1
            rotation = cutter.push(payload, stamp)
            if rotation is not None and (frame := decode(rotation)) is not None:
                yield frame
        rotation = cutter.finish()
        if rotation is not None and (frame := decode(rotation)) is not None:
            yield frame
        finish_read(stats, source)
