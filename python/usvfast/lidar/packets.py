"""Velodyne data packets: structural checks (size, block flags, return mode, model id),
decoding to points (`VelodyneScanDecoder`: usvfast's own decoder for the VLP-16, VLP-16 Hi-Res
and HDL-32E, velodyne-decoder for the other models), and the counts and warning every LiDAR
reader shares (`ReadStats`, `LidarDataWarning`).

Payload bytes that are corrupted but still structurally valid (a flipped distance byte)
cannot be detected: Velodyne sensors send UDP checksums of zero.
"""

from __future__ import annotations

import struct
import warnings
from collections import Counter
from dataclasses import dataclass, field

import numpy as np

from usvfast._core import decode_velodyne_scan
from usvfast._damage import DamagedRecordsWarning
from usvfast._extras import require
from usvfast.lidar.frame import POINT_DTYPE

#: Size of the UDP payload of a Velodyne data packet, bytes.
VELODYNE_PACKET_SIZE = 1206
#: Model ids (factory byte) known to velodyne-decoder's packet format.
_KNOWN_MODEL_IDS = {0x21, 0x22, 0x24, 0x28, 0x31, 0xA1}
_BLOCK_FLAGS = {0xEEFF, 0xDDFF}  # upper / lower block (HDL-64E uses both)
_RETURN_MODES = {0x37, 0x38, 0x39}
#: The flag and azimuth (u16 LE) at the head of each of the 12 blocks of 100 bytes.
_BLOCK_HEADS = struct.Struct("<" + "HH96x" * 12)
#: Model id -> model name of the sensors usvfast decodes itself (`_core.decode_velodyne_scan`).
NATIVE_MODELS = {0x21: "HDL-32E", 0x22: "VLP-16", 0x24: "VLP-16 Hi-Res"}


class LidarDataWarning(DamagedRecordsWarning):
    """Damaged LiDAR records were skipped while reading (count in the message); a
    DamagedRecordsWarning like every reader's."""


@dataclass
class ReadStats:
    """Counts kept by a reader while it streams.

    `records` counts pcap records or bag messages seen, `packets` Velodyne data packets
    decoded, `frames` frames produced, `damaged` skipped damaged records/packets/messages;
    `reasons` breaks `damaged` down by cause.
    """

    records: int = 0
    packets: int = 0
    frames: int = 0
    damaged: int = 0
    reasons: Counter = field(default_factory=Counter)

    def damage(self, reason: str, count: int = 1) -> None:
        """Count `count` damaged items for `reason`."""
        self.damaged += count
        self.reasons[reason] += count


def finish_read(stats: ReadStats, source: str) -> None:
    """At the end of a stream from `source`: warn with the damaged-record counts (a
    `LidarDataWarning`), or raise ValueError naming `source` when nothing usable was read."""
    if stats.damaged:
        detail = ", ".join(f"{k}: {v}" for k, v in sorted(stats.reasons.items()))
        warnings.warn(
            f"{source}: skipped {stats.damaged} damaged record(s) ({detail})",
            LidarDataWarning,
            stacklevel=3,
        )
    if stats.frames == 0:
        raise ValueError(f"{source}: no usable LiDAR frame (damaged: {stats.damaged})")


def velodyne_packet_problem(payload: bytes, model_id: int | None = None) -> str | None:
    """Return why a 1206-byte Velodyne data packet is malformed, or None if it looks valid.

    Checks the block flags, the azimuths (< 36000 hundredths of a degree), the factory bytes
    (return mode, model id, and the model id against `model_id` when given).
    """
    if len(payload) != VELODYNE_PACKET_SIZE:
        return "packet length"
    heads = _BLOCK_HEADS.unpack_from(payload)  # flag, azimuth of each of the 12 blocks
    if not _BLOCK_FLAGS.issuperset(heads[0::2]):
        return "block flag"
    if max(heads[1::2]) >= 36000:
        return "azimuth"
    return_mode, model = payload[1204], payload[1205]
    if return_mode not in _RETURN_MODES or model not in _KNOWN_MODEL_IDS:
        return "factory bytes"
    if model_id is not None and model != model_id:
        return "model id"
    return None


# lookup tables: value -> valid (one gather per check, no np.isin sort)
_FLAG_OK = np.zeros(1 << 16, dtype=bool)
_FLAG_OK[sorted(_BLOCK_FLAGS)] = True
_RETURN_OK = np.zeros(256, dtype=bool)
_RETURN_OK[sorted(_RETURN_MODES)] = True
_MODEL_OK = np.zeros(256, dtype=bool)
_MODEL_OK[sorted(_KNOWN_MODEL_IDS)] = True
_PROBLEMS = {1: "block flag", 2: "azimuth", 3: "factory bytes"}


def packet_problems(payloads: list[bytes]) -> list[str | None]:
    """`velodyne_packet_problem(p)` (without the model-id check) of many packets at once: one
    numpy pass over the packets of full length, the others one by one."""
    full = [k for k, p in enumerate(payloads) if len(p) == VELODYNE_PACKET_SIZE]
    out: list[str | None] = [None] * len(payloads)
    for k in set(range(len(payloads))) - set(full):
        out[k] = velodyne_packet_problem(payloads[k])
    if not full:
        return out
    raw = np.frombuffer(b"".join(payloads[k] for k in full), dtype=np.uint8)
    raw = raw.reshape(len(full), VELODYNE_PACKET_SIZE)
    blocks = raw[:, :1200].copy().view("<u2").reshape(len(full), 12, 50)
    bad_flag = (~_FLAG_OK[blocks[:, :, 0]]).any(axis=1)
    bad_azimuth = (blocks[:, :, 1] >= 36000).any(axis=1)
    bad_factory = ~(_RETURN_OK[raw[:, 1204]] & _MODEL_OK[raw[:, 1205]])
    # the first problem of each packet, in the order of velodyne_packet_problem's checks
    code = np.where(bad_flag, 1, np.where(bad_azimuth, 2, np.where(bad_factory, 3, 0)))
    bad = code.nonzero()[0]
    for j, c in zip(bad.tolist(), code[bad].tolist(), strict=True):
        out[full[j]] = _PROBLEMS[c]
    return out


def decoded_to_points(arr: np.ndarray) -> np.ndarray:
    """velodyne-decoder's (n, 8) float32 columns -> (n,) `POINT_DTYPE`."""
    out = np.empty(arr.shape[0], dtype=POINT_DTYPE)
    out["x"], out["y"], out["z"] = arr[:, 0], arr[:, 1], arr[:, 2]
    out["intensity"] = arr[:, 3]
    out["time"] = arr[:, 4]
    out["ring"] = arr[:, 6].astype(np.uint16)
    return out


class VelodyneScanDecoder:
    """Decodes the packets of one rotation at a time as one velodyne-decoder
    `ScanDecoder(Config(model=model))` does over a stream of rotations, to the same points and
    stamps bit for bit: VLP-16, VLP-16 Hi-Res and HDL-32E packets by usvfast's decoder, the
    other models by velodyne-decoder.

    `model`: a `velodyne_decoder.Model` or None. None takes the model from the first rotation
    decoded; after that (or with a model set) a rotation of another model id raises
    RuntimeError, as velodyne-decoder does. A model usvfast does not decode (HDL-64E, VLP-32,
    VLS-128) sends every rotation to velodyne-decoder.
    """

    def __init__(self, model: object | None = None) -> None:
        self.model = model
        self._model_id: int | None = None  # the model id the stream is bound to
        self._native = model is None
        if model is not None:
            vd = require("velodyne_decoder", "lidar", "Velodyne packets")
            native = {vd.Model.HDL32E: 0x21, vd.Model.VLP16: 0x22, vd.Model.PuckHiRes: 0x24}
            if isinstance(model, vd.Model) and model in native:
                self._native = True
                self._model_id = native[model]
        self._peer = None

    def _check_model(self, model_id: int) -> None:
        """Raise RuntimeError when the stream is bound to another model id than `model_id`."""
        if self._model_id is not None and model_id != self._model_id:
            raise RuntimeError(
                f"Expected model ID <{self._model_id}> in packet, got <{model_id}>. Note: if "
                "the device is HDL-64E, please set the model in Config explicitly."
            )  # velodyne-decoder's words: the pcap reader lets the last rotation's error out

    def skip(self, payloads: list[bytes]) -> bool:
        """Move the stream past one rotation without decoding it when what `decode` would do is
        known without decoding (usvfast's models: it decodes every rotation of the bound model
        id): returns True, and the stream is as `decode` leaves it. Returns False, untouched,
        when only decoding tells (velodyne-decoder's models). `payloads` as for `decode`;
        raises RuntimeError where `decode` would (another model id)."""
        model_id = payloads[0][1205]
        self._check_model(model_id)
        if not (self._native and model_id in NATIVE_MODELS):
            return False
        if self.model is None:
            self._model_id = model_id
        return True

    def decode(
        self, payloads: list[bytes], packet_times: list[float]
    ) -> tuple[tuple[float, float], np.ndarray]:
        """((host stamp, device stamp) UNIX s, (n, 8) float32 columns x, y, z, intensity, time,
        column, ring, return type) of one rotation's packets, which must pass
        `packet_problems` and share one model id; `packet_times` are their host times, UNIX s.
        Raises RuntimeError for a rotation the stream's decoder refuses (another model id, a
        model velodyne-decoder cannot decode)."""
        model_id = payloads[0][1205]
        self._check_model(model_id)
        if self._native and model_id in NATIVE_MODELS:
            raw = np.frombuffer(b"".join(payloads), dtype=np.uint8)
            times = np.array(packet_times, dtype=np.float64)
            stamps, points = decode_velodyne_scan(
                raw.reshape(len(payloads), VELODYNE_PACKET_SIZE), times, NATIVE_MODELS[model_id]
            )
        else:
            vd = require("velodyne_decoder", "lidar", "Velodyne packets")
            if self._peer is None:
                self._peer = vd.ScanDecoder(vd.Config(model=self.model))
            packets = [vd.VelodynePacket(t, p) for t, p in zip(packet_times, payloads, strict=True)]
            pair, points = self._peer.decode(vd.PacketVector(packets))
            stamps = (pair.host, pair.device)
        if self.model is None:
            self._model_id = model_id
        return stamps, points
