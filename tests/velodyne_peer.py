"""The bag reader as it was before it had its own Velodyne decoder (`PeerBagReader`): every
rotation's packets checked, then decoded by one velodyne-decoder `ScanDecoder`. The peer of
`test_velodyne_decoder.py` and `benches/bench_velodyne_decode.py`."""

from __future__ import annotations

import numpy as np
import velodyne_decoder as vd

from usvfast._time import ros_stamp_seconds
from usvfast.lidar.packets import decoded_to_points, packet_problems
from usvfast.lidar.readers import BagReader


class PeerBagReader(BagReader):
    """The bag reader decoding every rotation with velodyne-decoder, as it did before it had
    its own decoder (one `ScanDecoder` for the whole stream)."""

    def _decode_scan(self, msg, decoder, stats):
        if not hasattr(self, "_peer"):
            self._peer = vd.ScanDecoder(vd.Config(model=self.model))
        packets = []
        model_id = None
        payloads = [bytes(np.asarray(pkt.data, dtype=np.uint8)) for pkt in msg.packets]
        for pkt, payload, problem in zip(
            msg.packets, payloads, packet_problems(payloads), strict=True
        ):
            if problem is None and model_id is not None and payload[1205] != model_id:
                problem = "model id"
            if problem is not None:
                stats.damage(problem)
                continue
            model_id = payload[1205]
            packets.append(vd.VelodynePacket(ros_stamp_seconds(pkt.stamp), payload))
        if not packets:
            stats.damage("empty scan")
            return None
        stats.packets += len(packets)
        try:
            pair, arr = self._peer.decode(vd.PacketVector(packets))
        except RuntimeError:
            stats.damage("decoder")
            return None
        return float(pair.device if self.device_time else pair.host), decoded_to_points(arr)
