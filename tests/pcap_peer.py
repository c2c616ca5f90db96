"""The Velodyne pcap reader as it was before it had its own rotation cutter and decoder
(`PeerPcapReader`): the peer of `test_pcap_reader.py` and `benches/bench_pcap_reader.py`."""

from __future__ import annotations

from collections.abc import Iterator

import velodyne_decoder as vd

from usvfast.lidar.frame import LidarFrame
from usvfast.lidar.packets import (
    VELODYNE_PACKET_SIZE,
    ReadStats,
    decoded_to_points,
    finish_read,
    velodyne_packet_problem,
)
from usvfast.lidar.pcap import VelodynePcapReader, _iter_pcap_records, _udp_payload


class PeerPcapReader(VelodynePcapReader):
    """The pcap reader as it was before it had its own rotation cutter and decoder: every
    packet goes to one velodyne-decoder `StreamDecoder`, which cuts and decodes rotations."""

    def _frames(self, data) -> Iterator[LidarFrame]:
        self.stats = stats = ReadStats()
        source = str(self.path)
        decoder = vd.StreamDecoder(vd.Config(model=self.model))
        model_id: int | None = None

        def emit(result: tuple) -> LidarFrame:
            stamp_pair, arr = result
            stamp = stamp_pair.device if self.device_time else stamp_pair.host
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
                continue
            problem = velodyne_packet_problem(payload, model_id)
            if problem is not None:
                stats.damage(problem)
                continue
            model_id = payload[1205]
            stats.packets += 1
            try:
                result = decoder.decode(stamp, payload)
            except RuntimeError:
                stats.damage("decoder")
                decoder = vd.StreamDecoder(vd.Config(model=self.model))
                continue
            if result is not None:
                yield emit(result)
        result = decoder.finish()
        if result is not None:
            yield emit(result)
        finish_read(stats, source)
