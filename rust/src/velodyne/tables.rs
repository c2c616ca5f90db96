//! velodyne-decoder's default calibration of each model, its firing-time tables and the
//! azimuth sine/cosine table, built once per process.

use super::decode::{VelodyneModel, BLOCKS, CHANNELS};
use std::cmp::Ordering;
use std::hint::black_box;
use std::sync::OnceLock;

const AZIMUTH_UNITS: usize = 36_000;

/// Metres per distance count (2 mm for every model here), single as the decoder holds it.
pub(crate) const DISTANCE_RESOLUTION_M: f32 = 0.002_f64 as f32;

/// Laser elevations by laser id, degrees (user manuals' vertical angle tables).
const VLP16_ELEVATION_DEG: [f64; 16] = [
    -15.0, 1.0, -13.0, 3.0, -11.0, 5.0, -9.0, 7.0, -7.0, 9.0, -5.0, 11.0, -3.0, 13.0, -1.0, 15.0,
];
const VLP16_HI_RES_ELEVATION_DEG: [f64; 16] = [
    -10.0, 0.667, -8.667, 2.0, -7.333, 3.333, -6.0, 4.667, -4.667, 6.0, -3.333, 7.333, -2.0, 8.667,
    -0.667, 10.0,
];
const HDL32E_ELEVATION_DEG: [f64; 32] = [
    -30.67, -9.33, -29.33, -8.0, -28.0, -6.67, -26.67, -5.33, -25.33, -4.0, -24.0, -2.67, -22.67,
    -1.33, -21.33, 0.0, -20.0, 1.33, -18.67, 2.67, -17.33, 4.0, -16.0, 5.33, -14.67, 6.67, -13.33,
    8.0, -12.0, 9.33, -10.67, 10.67,
];
/// Height of each laser's origin above the sensor's optical centre, m (envelope drawings).
const VLP16_HI_RES_VERTICAL_OFFSET_M: [f64; 16] = [
    7.4e-3, -0.9e-3, 6.5e-3, -1.8e-3, 5.5e-3, -2.7e-3, 4.6e-3, -3.7e-3, 3.7e-3, -4.6e-3, 2.7e-3,
    -5.5e-3, 1.8e-3, -6.5e-3, 0.9e-3, -7.4e-3,
];
const HDL32E_VERTICAL_OFFSET_M: [f64; 32] = [
    17.17e-3, 4.76e-3, 16.27e-3, 4.07e-3, 15.4e-3, 3.38e-3, 14.54e-3, 2.7e-3, 13.71e-3, 2.02e-3,
    12.89e-3, 1.35e-3, 12.09e-3, 0.67e-3, 11.31e-3, 0.0, 10.54e-3, -0.67e-3, 9.78e-3, -1.35e-3,
    9.04e-3, -2.02e-3, 8.3e-3, -2.7e-3, 7.58e-3, -3.38e-3, 6.86e-3, -4.07e-3, 6.15e-3, -4.76e-3,
    5.45e-3, -5.45e-3,
];
/// VLP-16: distance from the rotation axis to the point where the beams cross, m; a laser's
/// origin is `-focal · tan(elevation)` above the centre.
const VLP16_FOCAL_DISTANCE_M: f64 = 41.91e-3;

/// One laser's calibration, single precision.
pub(crate) struct Laser {
    pub cos_vert: f32,
    pub sin_vert: f32,
    /// Height of the laser's origin, m.
    pub vert_offset: f32,
    /// Rank of the laser's elevation, 0 = lowest.
    pub ring: f32,
}

/// A model's lasers (by laser id), firing times and columns per block.
pub(crate) struct ModelTables {
    pub lasers: Vec<Laser>,
    /// Firing time of (block, channel) from the packet's first firing, s.
    pub timing: [[f32; CHANNELS]; BLOCKS],
    /// `timing[row][ch] - timing[row][0]`, s: the time from the row's first firing.
    pub since_first: [[f32; CHANNELS]; BLOCKS],
    /// The laser (by laser id) of each channel of a block, and whether it belongs to the
    /// block's second firing sequence (its column is one more).
    pub channel_laser: [(u8, bool); CHANNELS],
    /// Firing sequences (columns) per block: 2 for the 16-laser models, 1 for the HDL-32E.
    pub columns_per_block: u16,
}

impl ModelTables {
    /// The tables of `model`, built on first use.
    pub(crate) fn of(model: VelodyneModel) -> &'static ModelTables {
        static TABLES: [OnceLock<ModelTables>; 3] =
            [OnceLock::new(), OnceLock::new(), OnceLock::new()];
        let slot = match model {
            VelodyneModel::Hdl32e => 0,
            VelodyneModel::Vlp16 => 1,
            VelodyneModel::Vlp16HiRes => 2,
        };
        TABLES[slot].get_or_init(|| Self::build(model))
    }

    fn build(model: VelodyneModel) -> ModelTables {
        let (elevations, offsets): (&[f64], Option<&[f64]>) = match model {
            VelodyneModel::Vlp16 => (&VLP16_ELEVATION_DEG, None),
            VelodyneModel::Vlp16HiRes => (
                &VLP16_HI_RES_ELEVATION_DEG,
                Some(&VLP16_HI_RES_VERTICAL_OFFSET_M),
            ),
            VelodyneModel::Hdl32e => (&HDL32E_ELEVATION_DEG, Some(&HDL32E_VERTICAL_OFFSET_M)),
        };
        // angles held as single degrees, converted to radians in double, rounded to single;
        // black_box keeps the compiler from folding the C library's sinf/cosf/tanf
        let vert: Vec<f32> = elevations
            .iter()
            .map(|&deg| (f64::from(deg as f32) * std::f64::consts::PI / 180.0) as f32)
            .collect();
        let mut order: Vec<usize> = (0..vert.len()).collect();
        // stable, by `<` as the decoder sorts: ties keep laser order
        order.sort_by(|&a, &b| vert[a].partial_cmp(&vert[b]).unwrap_or(Ordering::Equal));
        let mut ring = vec![0.0_f32; vert.len()];
        for (r, &laser) in order.iter().enumerate() {
            ring[laser] = r as f32;
        }
        let lasers: Vec<Laser> = vert
            .iter()
            .enumerate()
            .map(|(i, &v)| {
                let v = black_box(v);
                let vert_offset = match offsets {
                    Some(o) => o[i] as f32,
                    None => (VLP16_FOCAL_DISTANCE_M as f32) * (-v).tan(),
                };
                Laser {
                    cos_vert: v.cos(),
                    sin_vert: v.sin(),
                    vert_offset,
                    ring: ring[i],
                }
            })
            .collect();
        let timing = firing_times(model);
        let since_first = timing.map(|row| row.map(|t| t - row[0]));
        let per_block = lasers.len();
        let channel_laser = std::array::from_fn(|ch| ((ch % per_block) as u8, ch >= per_block));
        ModelTables {
            lasers,
            timing,
            since_first,
            channel_laser,
            columns_per_block: if model == VelodyneModel::Hdl32e { 1 } else { 2 },
        }
    }
}

/// Firing time of each (block, channel) from the packet's first firing, s (user manuals'
/// timing tables): VLP-16 sequences every 55.296 µs, two per block, lasers 2.304 µs apart;
/// HDL-32E firings every 46.080 µs, one per block, lasers 1.152 µs apart. Double, rounded
/// to single.
fn firing_times(model: VelodyneModel) -> [[f32; CHANNELS]; BLOCKS] {
    let mut t = [[0.0_f32; CHANNELS]; BLOCKS];
    for (block, row) in t.iter_mut().enumerate() {
        for (ch, cell) in row.iter_mut().enumerate() {
            let (sequence, laser, period, spacing) = match model {
                VelodyneModel::Hdl32e => (block, ch, 46.080 * 1e-6, 1.152 * 1e-6),
                _ => (2 * block + ch / 16, ch % 16, 55.296 * 1e-6, 2.304 * 1e-6),
            };
            *cell = (period * sequence as f64 + spacing * laser as f64) as f32;
        }
    }
    t
}

/// Cosine and sine of every azimuth count (0.01°), single.
pub(crate) struct RotationTable {
    /// `[cos, sin]` of azimuth count `i` at index `i`.
    pub cos_sin: Vec<[f32; 2]>,
}

/// The table, built on first use.
pub(crate) fn rotation_table() -> &'static RotationTable {
    static TABLE: OnceLock<RotationTable> = OnceLock::new();
    TABLE.get_or_init(|| {
        let deg_to_rad = (std::f64::consts::PI / 180.0) as f32;
        let cos_sin = (0..AZIMUTH_UNITS)
            .map(|units| {
                let a = black_box(0.01_f32 * units as f32 * deg_to_rad);
                [a.cos(), a.sin()]
            })
            .collect();
        RotationTable { cos_sin }
    })
}
