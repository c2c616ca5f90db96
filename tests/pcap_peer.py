"""The Velodyne pcap reader as it was before it had its own rotation cutter and decoder
(`PeerPcapReader`): UDP payloads taken out by dpkt, packets checked by numpy, every packet
through one velodyne-decoder `StreamDecoder`; a refusal of the last rotation is counted as
damage, as every other refusal (it raised RuntimeError before). The peer of `test_pcap_reader.py`
and `benches/bench_pcap_reader.py`."""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
import velodyne_decoder as vd

from usvfast.lidar.frame import LidarFrame
from usvfast.lidar.packets import (
    _BLOCK_FLAGS,
    _KNOWN_MODEL_IDS,
    _RETURN_MODES,
    VELODYNE_PACKET_SIZE,
    ReadStats,
    decoded_to_points,
    finish_read,
)
from usvfast.lidar.pcap import VelodynePcapReader, _iter_pcap_records
from usvfast.lidar.pcap import _udp_payload as udp_payload  # unchanged: dpkt reads the frames


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
                udp = udp_payload(linktype, frame_bytes)
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
            problem = packet_problem(payload, model_id)
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
        try:
            result = decoder.finish()
        except RuntimeError:  # counted, as the refusals above (the reader's damage policy)
            stats.damage("decoder")
            result = None
        if result is not None:
            yield emit(result)
        finish_read(stats, source)
