//! Decoding one rotation's packets (see the [module doc](super)).

use super::tables::{rotation_table, Laser, ModelTables, RotationTable, DISTANCE_RESOLUTION_M};
use crate::error::{check_finite, Error, Result};

/// Size of one data packet (the UDP payload), bytes.
pub const PACKET_SIZE: usize = 1206;
/// Columns of a decoded point: x, y, z (m, sensor frame), intensity (0–255), time (s from the
/// scan stamp's device time), column (firing sequence index in the scan), ring (laser index
/// by elevation, 0 = lowest), return type ([`RETURN_STRONGEST`], [`RETURN_LAST`],
/// [`RETURN_BOTH`]).
pub const POINT_COLUMNS: usize = 8;
/// Shortest distance kept, m (velodyne-decoder's default `min_range`, 0.1 as single).
pub const MIN_RANGE_M: f32 = 0.1_f64 as f32;
/// Longest distance kept, m (velodyne-decoder's Python default `max_range`).
pub const MAX_RANGE_M: f32 = 200.0;
/// Return type of the strongest return (single strongest mode, or dual mode when it differs
/// from the last one).
pub const RETURN_STRONGEST: f32 = 1.0;
/// Return type of the last return (single last mode, or dual mode when it differs from the
/// strongest one).
pub const RETURN_LAST: f32 = 2.0;
/// Return type of a dual-mode return that is both the last and the strongest one.
pub const RETURN_BOTH: f32 = 3.0;

pub(crate) const BLOCKS: usize = 12;
pub(crate) const BLOCK_SIZE: usize = 100;
pub(crate) const CHANNELS: usize = 32;
pub(crate) const BLOCK_FLAG: u16 = 0xEEFF;
pub(crate) const MODE_STRONGEST: u8 = 0x37;
pub(crate) const MODE_LAST: u8 = 0x38;
pub(crate) const MODE_DUAL: u8 = 0x39;
const STAMP_AT: usize = 1200;
pub(crate) const MODE_AT: usize = 1204;
pub(crate) const MODEL_AT: usize = 1205;

/// The sensor models this decoder covers, named by their packet model id.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum VelodyneModel {
    /// VLP-16 (Puck, Puck LITE): 16 lasers, −15° to +15° every 2°; model id 0x22.
    Vlp16,
    /// VLP-16 Hi-Res (Puck Hi-Res): 16 lasers, −10° to +10° every 1.33°; model id 0x24.
    Vlp16HiRes,
    /// HDL-32E: 32 lasers, −30.67° to +10.67° every 1.33°; model id 0x21.
    Hdl32e,
}

impl VelodyneModel {
    /// Every model, in packet-id order.
    pub const ALL: [VelodyneModel; 3] = [Self::Hdl32e, Self::Vlp16, Self::Vlp16HiRes];

    /// The model id byte (offset 1205) of this model's packets.
    #[must_use]
    pub fn packet_id(self) -> u8 {
        match self {
            Self::Hdl32e => 0x21,
            Self::Vlp16 => 0x22,
            Self::Vlp16HiRes => 0x24,
        }
    }

    /// The model whose packets carry model id `id`, or None for models not covered here.
    #[must_use]
    pub fn from_packet_id(id: u8) -> Option<Self> {
        Self::ALL.into_iter().find(|m| m.packet_id() == id)
    }

    /// The model's name: "VLP-16", "VLP-16 Hi-Res" or "HDL-32E".
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Hdl32e => "HDL-32E",
            Self::Vlp16 => "VLP-16",
            Self::Vlp16HiRes => "VLP-16 Hi-Res",
        }
    }

    /// The model named `name` (as [`VelodyneModel::name`] spells it), or None.
    #[must_use]
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|m| m.name() == name)
    }
}

/// One decoded rotation: the stamps of its last packet and its points.
#[derive(Clone, Debug, PartialEq)]
pub struct DecodedScan {
    /// Host time of the last packet, UNIX s.
    pub host_stamp: f64,
    /// Device time of the last packet, UNIX s ([`device_time`]); the `time` column is
    /// relative to it.
    pub device_stamp: f64,
    /// `(n, POINT_COLUMNS)` row-major points (see [`POINT_COLUMNS`]), in packet order.
    pub points: Vec<f32>,
}

impl DecodedScan {
    /// Number of points.
    #[must_use]
    pub fn len(&self) -> usize {
        self.points.len() / POINT_COLUMNS
    }

    /// True when no return survived.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }
}

/// Device time of a packet, UNIX s: the hour of `host_time` (UNIX s) plus the packet's
/// `micros_past_hour`, moved by an hour when that lands more than half an hour from
/// `host_time` (hosts at or before the epoch are not compared). The host hour is taken as the
/// decoder's x86-64 build computes it (whole seconds wrapped to 32 bits, unsigned).
#[must_use]
pub fn device_time(host_time: f64, micros_past_hour: u32) -> f64 {
    const HOUR: f64 = 3600.0;
    let seconds = host_time.floor();
    // double -> int64 as x86-64 converts it (out of range and NaN give i64::MIN), then the
    // low 32 bits as unsigned
    let whole = if (-9.223_372_036_854_776e18..9.223_372_036_854_776e18).contains(&seconds) {
        seconds as i64
    } else {
        i64::MIN
    };
    let hour_start = (whole as u32) / 3600 * 3600;
    let t = f64::from(hour_start) + f64::from(micros_past_hour) * 1e-6;
    if host_time > 0.0 {
        if t > host_time + HOUR / 2.0 {
            return t - HOUR;
        }
        if t < host_time - HOUR / 2.0 {
            return t + HOUR;
        }
    }
    t
}

/// Decodes the packets of one rotation, in order, to points.
///
/// `payloads`: k × [`PACKET_SIZE`] bytes, the packets back to back; `packet_times`: (k,) host
/// times of the packets, UNIX s. Every packet must carry `model`'s model id and a return mode
/// 0x37, 0x38 or 0x39. Blocks are read up to the first whose flag is not 0xEEFF (in dual mode
/// the flags of the strongest-return blocks are not looked at). Zero distances and distances
/// outside [[`MIN_RANGE_M`], [`MAX_RANGE_M`]] give no point.
///
/// Fails with [`Error::Dimension`] when the sizes disagree or there is no packet,
/// [`Error::NonFinite`] for a NaN or infinite time and [`Error::InvalidParameter`] naming
/// the packet for a wrong model id or return mode; nothing is decoded then.
pub fn decode_scan(
    model: VelodyneModel,
    payloads: &[u8],
    packet_times: &[f64],
) -> Result<DecodedScan> {
    let k = packet_times.len();
    if k == 0 || payloads.len() != k * PACKET_SIZE {
        return Err(Error::dim(
            "payloads",
            format!("k × {PACKET_SIZE} bytes with k = len(packet_times) ≥ 1 (k = {k})"),
            format!("{} bytes", payloads.len()),
        ));
    }
    check_finite("packet_times", packet_times)?;
    for (i, pkt) in payloads.chunks_exact(PACKET_SIZE).enumerate() {
        if pkt[MODEL_AT] != model.packet_id() {
            return Err(Error::param(
                "payloads",
                format!(
                    "packet {i} has model id {:#04x}, expected {:#04x} ({})",
                    pkt[MODEL_AT],
                    model.packet_id(),
                    model.name()
                ),
            ));
        }
        if !matches!(pkt[MODE_AT], MODE_STRONGEST | MODE_LAST | MODE_DUAL) {
            return Err(Error::param(
                "payloads",
                format!(
                    "packet {i} has return mode {:#04x}, expected 0x37, 0x38 or 0x39",
                    pkt[MODE_AT]
                ),
            ));
        }
    }
    let tables = ModelTables::of(model);
    let rotation = rotation_table();
    let device = |pkt: &[u8], host: f64| {
        let stamp = u32::from_le_bytes([
            pkt[STAMP_AT],
            pkt[STAMP_AT + 1],
            pkt[STAMP_AT + 2],
            pkt[STAMP_AT + 3],
        ]);
        device_time(host, stamp)
    };
    let host_stamp = packet_times[k - 1];
    let device_stamp = device(&payloads[(k - 1) * PACKET_SIZE..], host_stamp);
    let mut points = Vec::with_capacity(returns_bound(payloads) * POINT_COLUMNS);
    for (pkt, &host) in payloads.chunks_exact(PACKET_SIZE).zip(packet_times) {
        // time of the packet's first firing from the scan stamp, rounded to single
        let rel_stamp = (device(pkt, host) - device_stamp) as f32;
        decode_packet(tables, rotation, pkt, rel_stamp, &mut points);
    }
    Ok(DecodedScan {
        host_stamp,
        device_stamp,
        points,
    })
}

/// At least the number of points the packets give: their non-zero distances (in dual mode a
/// pair of blocks gives at most one point per non-zero distance too). Sizing the output by it
/// keeps the allocation near the result's size.
fn returns_bound(payloads: &[u8]) -> usize {
    payloads
        .chunks_exact(PACKET_SIZE)
        .flat_map(|pkt| pkt[..BLOCKS * BLOCK_SIZE].chunks_exact(BLOCK_SIZE))
        .map(|block| {
            block[4..]
                .chunks_exact(3)
                .filter(|r| r[0] | r[1] != 0)
                .count()
        })
        .sum()
}

fn block_u16(pkt: &[u8], block: usize, at: usize) -> u16 {
    let o = block * BLOCK_SIZE + at;
    u16::from_le_bytes([pkt[o], pkt[o + 1]])
}

/// `(a + 36000) mod 36000` as the decoder computes it (truncated remainder, kept to 16 bits).
fn wrap_units(a: i32) -> u16 {
    ((a + 36_000) % 36_000) as u16
}

/// An interpolated azimuth `a` (0.01° units, single, 0 ≤ a < 2¹⁷) shifted by a turn, rounded
/// half away from zero (`lroundf`) and wrapped into 0..36000.
pub(crate) fn wrap_azimuth(a: f32) -> usize {
    let shifted = a + 36_000.0_f32;
    // round half away from zero of a non-negative value below 2²³: the fraction after
    // truncation is exact
    let whole = shifted as u32;
    let rounded = whole + u32::from(shifted - whole as f32 >= 0.5);
    (rounded % 36_000) as usize
}

/// Appends the points of one packet to `points` (rows of [`POINT_COLUMNS`]); `rel_stamp`
/// is the time of its first firing from the scan stamp, s.
fn decode_packet(
    tables: &ModelTables,
    rotation: &RotationTable,
    pkt: &[u8],
    rel_stamp: f32,
    points: &mut Vec<f32>,
) {
    let mode = pkt[MODE_AT];
    let dual = mode == MODE_DUAL;
    let single_type = if mode == MODE_LAST {
        RETURN_LAST
    } else {
        RETURN_STRONGEST
    };
    // columns continue from the scan's last point (not from the last block)
    let mut column = match points.len() {
        0 => 0,
        n => (points[n - POINT_COLUMNS + 5] as u16).wrapping_add(1),
    };
    // mean rotation rate over the packet, 0.01° per second
    let first_to_last =
        wrap_units(i32::from(block_u16(pkt, BLOCKS - 1, 2)) - i32::from(block_u16(pkt, 0, 2)));
    let last_firing = if dual { (BLOCKS - 1) / 2 } else { BLOCKS - 1 };
    let duration = tables.timing[last_firing][0] - tables.timing[0][0];
    let rate = f32::from(first_to_last) / duration;
    let step = if dual { 2 } else { 1 };
    for block in (0..BLOCKS).step_by(step) {
        if block_u16(pkt, block, 0) != BLOCK_FLAG {
            return; // the decoder drops the rest of a packet at a foreign block
        }
        let row = if dual { block / 2 } else { block };
        let (timing, since_first) = (&tables.timing[row], &tables.since_first[row]);
        let azimuth = f32::from(block_u16(pkt, block, 2));
        let returns = &pkt[block * BLOCK_SIZE + 4..(block + 1) * BLOCK_SIZE];
        // dual mode: the strongest returns of the same firings, in the next block
        let strongest = if dual {
            &pkt[(block + 1) * BLOCK_SIZE + 4..(block + 2) * BLOCK_SIZE]
        } else {
            &[0_u8; 3 * CHANNELS][..]
        };
        for (ch, (first, second)) in returns
            .chunks_exact(3)
            .zip(strongest.chunks_exact(3))
            .enumerate()
        {
            let first = (u16::from_le_bytes([first[0], first[1]]), first[2]);
            let second = (u16::from_le_bytes([second[0], second[1]]), second[2]);
            if first.0 == 0 && second.0 == 0 {
                continue;
            }
            let az = wrap_azimuth(azimuth + rate * since_first[ch]);
            let [cos, sin] = rotation.cos_sin[az];
            let (laser, next_column) = tables.channel_laser[ch];
            let at = Firing {
                laser: &tables.lasers[usize::from(laser)],
                cos,
                sin,
                time: rel_stamp + timing[ch],
                column: column.wrapping_add(u16::from(next_column)),
            };
            if !dual {
                at.emit(first, single_type, points);
            } else if first.0 == second.0 {
                at.emit(second, RETURN_BOTH, points);
            } else {
                // first = last return, second = strongest return
                if first.0 > 0 {
                    at.emit(first, RETURN_LAST, points);
                }
                if second.0 > 0 {
                    at.emit(second, RETURN_STRONGEST, points);
                }
            }
        }
        column = column.wrapping_add(tables.columns_per_block);
    }
}

/// One laser's firing: its calibration, the sine and cosine of its azimuth, its time (s from
/// the scan stamp) and column.
struct Firing<'a> {
    laser: &'a Laser,
    cos: f32,
    sin: f32,
    time: f32,
    column: u16,
}

impl Firing<'_> {
    /// Appends the point of return `(distance counts, reflectivity)` when its distance is in
    /// range.
    fn emit(&self, (counts, reflectivity): (u16, u8), return_type: f32, points: &mut Vec<f32>) {
        let l = self.laser;
        let distance = f32::from(counts) * DISTANCE_RESOLUTION_M;
        if !(MIN_RANGE_M..=MAX_RANGE_M).contains(&distance) {
            return;
        }
        // The decoder turns the azimuth a by the laser's rotation correction b: cos(a − b) =
        // cos a · cos b + sin a · sin b. Every laser of these models has b = 0, and then that
        // is cos a bit for bit (· 1 is exact, + (±0) leaves a non-zero value alone, and only
        // sin 0 is zero, +0); likewise sin(a − b) is sin a (the tests check every entry).
        let xy = distance * l.cos_vert;
        let x = xy * self.cos;
        let y = -xy * self.sin;
        let z = distance * l.sin_vert + l.vert_offset;
        points.extend_from_slice(&[
            x,
            y,
            z,
            f32::from(reflectivity),
            self.time,
            f32::from(self.column),
            l.ring,
            return_type,
        ]);
    }
}
