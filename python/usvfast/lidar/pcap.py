"""Velodyne `.pcap` captures (`VelodynePcapReader`), one frame per rotation. The records, their
UDP/IPv4 datagrams and the packet checks are read in Rust over the memory-mapped file
(`_core.pcap_udp_datagrams`, `_core.velodyne_packet_check`: the same datagrams, the same
damage as the reader's former dpkt path, their oracle in tests/test_pcap_records.py); the
record stream resynchronises on the next plausible record header after a damaged record;
damaged records are skipped and counted (`usvfast.lidar.packets`), the counts kept up as a
record-by-record reader keeps them. The packets are cut into rotations (`RotationCutter`)
where velodyne-decoder's `StreamDecoder` cuts them and decoded by `VelodyneScanDecoder`: the
frames are the ones velodyne-decoder gives, bit for bit."""

from __future__ import annotations

import mmap
import os
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from usvfast._core import pcap_udp_datagrams, velodyne_packet_check
from usvfast._files import regular_file
from usvfast._validate import integer
from usvfast.lidar.frame import LidarFrame
from usvfast.lidar.packets import (
    VELODYNE_PACKET_SIZE,
    ReadStats,
    VelodyneScanDecoder,
    decoded_to_points,
    finish_read,
)

if TYPE_CHECKING:
    from usvfast._core import _PcapDatagrams


def _bytes_view(data) -> np.ndarray:
    """`data` (bytes or an mmap) as a uint8 array without a copy. The caller drops the view
    before the mmap is closed (a map with a live export cannot be closed)."""
    return np.frombuffer(data, dtype=np.uint8)


def _udp_datagrams(data, source: str) -> _PcapDatagrams:
    """`_core.pcap_udp_datagrams` of the capture `data` (bytes or an mmap): every UDP/IPv4
    datagram, the records seen and the damage skipped, read in one Rust pass. Raises
    ValueError naming `source` when `data` is not a libpcap file."""
    try:
        return pcap_udp_datagrams(_bytes_view(data))
    except ValueError as exc:  # the only one for a uint8 array: its header
        raise ValueError(f"{source}: not a libpcap file (pcapng is not supported)") from exc


class _Counts:
    """The counts of a capture read in one pass (`_core.pcap_udp_datagrams`), handed to a
    reader's `stats` as it hands its data packets on: after n packets, the records up to the
    n-th packet's record and the damage before it (a record's, before a datagram; a packet's,
    at it), as a record-by-record reader would have counted them."""

    def __init__(
        self,
        stats: ReadStats,
        found: _PcapDatagrams,
        kept: np.ndarray,
        damage: list[tuple[int, str]],
    ) -> None:
        self.stats = stats
        self.records = found["records"]
        self.record_counts = found["record_counts"][kept]
        # each damage with the number of packets handed on when it is counted
        at = np.searchsorted(kept, [d for d, _ in damage], side="left") + 1
        order = np.argsort(at, kind="stable")
        self.damage = [(int(at[k]), damage[k][1]) for k in order.tolist()]
        self.next = 0  # the next damage to count

    def count_to(self, packets: int | None) -> None:
        """Counts up to `packets` (≥ 1) packets handed on; None: the whole capture."""
        if packets is None:
            self.stats.records = self.records
            packets = len(self.record_counts) + 1  # past the last packet: every damage
        else:
            self.stats.records = int(self.record_counts[packets - 1])
        while self.next < len(self.damage) and self.damage[self.next][0] <= packets:
            self.stats.damage(self.damage[self.next][1])
            self.next += 1


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

    Packets must have passed `usvfast.lidar.packets.velodyne_packet_problem` (azimuths below
    36000). The cutter
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

    def _data_packets(
        self, data, stats: ReadStats, source: str
    ) -> tuple[Iterator[tuple[float, bytes]], Callable[[int | None], None]]:
        """(packets, count_to): the (host time UNIX s, payload) of each well-formed data
        packet of the capture `data`, in capture order, and what brings `stats` to where a
        record-by-record reader would have it after the first n of them (`count_to(n)`; None:
        the end). The packets are the UDP datagrams of the packet size (on `data_port` when
        it is set, where one of another size is "packet length" damage; others are position /
        telemetry packets) that pass `velodyne_packet_problem` against the model id of the
        last packet that passed (the others are counted by their problem). The records are
        read and the packets checked in Rust (`_core.pcap_udp_datagrams`,
        `_core.velodyne_packet_check`) before the first packet is handed on."""
        found = _udp_datagrams(data, source)
        times, ports, offsets = found["times"], found["ports"], found["offsets"]
        data_packets = found["lengths"] == VELODYNE_PACKET_SIZE
        # (datagram, label): a record's damage sits before that datagram, a packet's at it
        damage = found["damage"]
        if self.data_port is not None:
            on_port = ports == self.data_port
            wrong_length = np.flatnonzero(on_port & ~data_packets).tolist()
            damage += [(k, "packet length") for k in wrong_length]
            data_packets &= on_port
        candidates = np.flatnonzero(data_packets)
        passed, problems = velodyne_packet_check(_bytes_view(data), offsets[candidates])
        damage += [(int(candidates[j]), label) for j, label in problems]
        kept = candidates[passed]
        starts = offsets[kept].tolist()
        packets = (
            (stamp, data[start : start + VELODYNE_PACKET_SIZE])
            for stamp, start in zip(times[kept].tolist(), starts, strict=True)
        )
        return packets, _Counts(stats, found, kept, damage).count_to

    def _frames(self, data) -> Iterator[LidarFrame]:
        self.stats = stats = ReadStats()
        source = str(self.path)
        decoder = VelodyneScanDecoder(self.model)
        cutter = RotationCutter()

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

        packets, count_to = self._data_packets(data, stats, source)
        for stamp, payload in packets:
            stats.packets += 1
            rotation = cutter.push(payload, stamp)
            if rotation is not None and (frame := decode(rotation)) is not None:
                count_to(stats.packets)  # a caller may stop here: the counts so far
                yield frame
        count_to(None)
        rotation = cutter.finish()
        if rotation is not None and (frame := decode(rotation)) is not None:
            yield frame
        finish_read(stats, source)
