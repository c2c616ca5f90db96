//! Velodyne VLP-16, VLP-16 Hi-Res and HDL-32E data packets decoded to points, bit for bit as
//! velodyne-decoder 3.1 (`ScanDecoder` with its default `Config` and calibration) decodes them.
//!
//! A data packet is the 1206-byte UDP payload the sensor sends (VLP-16 and HDL-32E user
//! manuals, "Data Packet Format"):
//!
//! ```text
//! 12 blocks × [ flag: bytes FF EE (0xEEFF as u16 LE) | azimuth, 0.01° (u16)
//!               | 32 × (distance, 2 mm (u16), reflectivity (u8)) ]
//! timestamp of the first firing, µs past the hour (u32) | return mode | model id
//! ```
//!
//! Return mode 0x37 = strongest, 0x38 = last, 0x39 = dual (block pairs: last, strongest);
//! model id 0x21 = HDL-32E, 0x22 = VLP-16, 0x24 = VLP-16 Hi-Res. A VLP-16 block holds two
//! firing sequences of its 16 lasers, an HDL-32E block one firing of its 32 lasers.
//!
//! Each point gets an azimuth interpolated within its block at the packet's mean rotation
//! rate and its laser's firing time; positions are in the sensor frame as Velodyne reports
//! them (x forward, y left, z up, metres). Bit-exactness comes from doing every operation the
//! way that decoder does: single precision in the same order, no fused multiply-add, the
//! same double-precision tables rounded once to single, and the sine, cosine and tangent
//! tables from the platform's C library (`sinf`/`cosf`/`tanf`, as the decoder calls them).
//!
//! [`check`] refuses malformed packets; [`decode`] reads the packets; `tables` holds each model's calibration (vertical angles
//! and offsets, firing times) and the azimuth sine/cosine table.

pub mod check;
pub mod decode;
mod tables;

pub use check::{packet_problem, stream_problems, PacketProblem};
pub use decode::{
    decode_scan, device_time, DecodedScan, VelodyneModel, MAX_RANGE_M, MIN_RANGE_M, PACKET_SIZE,
    POINT_COLUMNS, RETURN_BOTH, RETURN_LAST, RETURN_STRONGEST,
};

#[cfg(test)]
mod tests;
