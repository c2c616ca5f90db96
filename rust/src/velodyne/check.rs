//! Structural checks of data packets before they are cut into rotations: what usvfast's
//! readers count as a damaged packet (`usvfast.lidar.packets.velodyne_packet_problem`, the
//! oracle of `tests/test_pcap_records.py`).

use super::decode::{
    BLOCKS, BLOCK_FLAG, BLOCK_SIZE, MODEL_AT, MODE_AT, MODE_DUAL, MODE_LAST, MODE_STRONGEST,
    PACKET_SIZE,
};

/// Upper and lower block flags (the HDL-64E uses both), as u16 little-endian.
const BLOCK_FLAGS: [u16; 2] = [BLOCK_FLAG, 0xDDFF];
/// One turn in azimuth units (0.01°); a block azimuth must be below it.
const FULL_TURN: u16 = 36_000;
const RETURN_MODES: [u8; 3] = [MODE_STRONGEST, MODE_LAST, MODE_DUAL];
/// Model ids of velodyne-decoder's packet format: HDL-32E, VLP-16, VLP-16 Hi-Res, VLP-32C,
/// VLS-128, HDL-64E.
const KNOWN_MODEL_IDS: [u8; 6] = [0x21, 0x22, 0x24, 0x28, 0x31, 0xA1];

/// Why a data packet is refused, in the order the checks run.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum PacketProblem {
    /// Not [`PACKET_SIZE`] bytes.
    Length,
    /// A block flag other than 0xEEFF / 0xDDFF.
    BlockFlag,
    /// A block azimuth of a full turn or more.
    Azimuth,
    /// An unknown return mode or model id.
    FactoryBytes,
    /// A model id other than the stream's.
    ModelId,
}

impl PacketProblem {
    /// Every problem, in check order.
    pub const ALL: [PacketProblem; 5] = [
        Self::Length,
        Self::BlockFlag,
        Self::Azimuth,
        Self::FactoryBytes,
        Self::ModelId,
    ];

    /// The readers' damage label ("packet length", "block flag", "azimuth", "factory
    /// bytes", "model id").
    #[must_use]
    pub fn label(self) -> &'static str {
        match self {
            Self::Length => "packet length",
            Self::BlockFlag => "block flag",
            Self::Azimuth => "azimuth",
            Self::FactoryBytes => "factory bytes",
            Self::ModelId => "model id",
        }
    }
}

fn le16(b: &[u8], at: usize) -> u16 {
    u16::from_le_bytes([b[at], b[at + 1]])
}

/// The first problem of `payload` (a UDP payload), or None when it is a well-formed data
/// packet: [`PACKET_SIZE`] bytes, every block flagged 0xEEFF or 0xDDFF with an azimuth below
/// 36000, a known return mode and model id, and the model id `model_id` when given.
#[must_use]
pub fn packet_problem(payload: &[u8], model_id: Option<u8>) -> Option<PacketProblem> {
    if payload.len() != PACKET_SIZE {
        return Some(PacketProblem::Length);
    }
    let heads = || (0..BLOCKS).map(|b| b * BLOCK_SIZE);
    if heads().any(|at| !BLOCK_FLAGS.contains(&le16(payload, at))) {
        return Some(PacketProblem::BlockFlag);
    }
    if heads().any(|at| le16(payload, at + 2) >= FULL_TURN) {
        return Some(PacketProblem::Azimuth);
    }
    let (mode, model) = (payload[MODE_AT], payload[MODEL_AT]);
    if !RETURN_MODES.contains(&mode) || !KNOWN_MODEL_IDS.contains(&model) {
        return Some(PacketProblem::FactoryBytes);
    }
    if model_id.is_some_and(|id| id != model) {
        return Some(PacketProblem::ModelId);
    }
    None
}

/// [`packet_problem`] of a stream of packets, each checked against the model id of the last
/// packet that passed (none before the first): the packets are `data[o..o + PACKET_SIZE]` for
/// each offset `o` in `offsets` (a packet running past the end of `data` is
/// [`PacketProblem::Length`]).
#[must_use]
pub fn stream_problems(data: &[u8], offsets: &[usize]) -> Vec<Option<PacketProblem>> {
    let mut model_id = None;
    offsets
        .iter()
        .map(|&o| {
            let payload = data.get(o..o.saturating_add(PACKET_SIZE)).unwrap_or(&[]);
            let problem = packet_problem(payload, model_id);
            if problem.is_none() {
                model_id = Some(payload[MODEL_AT]);
            }
            problem
        })
        .collect()
}
