//! Hand-built packets through the decoder (bit-exactness against velodyne-decoder itself is
//! tested from Python, `tests/test_velodyne_decoder.py`).

use super::decode::wrap_azimuth;
use super::tables::rotation_table;
use super::*;
use crate::error::{Error, Result};
use std::hint::black_box;

const START: f64 = 1_686_909_600.0; // a whole hour, UNIX s

/// A packet of `model` in `mode` with every block flagged 0xEEFF, the given block azimuths
/// and no return; its device time is `micros` past the hour.
fn packet(model: VelodyneModel, mode: u8, azimuths: [u16; 12], micros: u32) -> Vec<u8> {
    let mut p = vec![0_u8; PACKET_SIZE];
    for (b, az) in azimuths.iter().enumerate() {
        p[b * 100..b * 100 + 2].copy_from_slice(&0xEEFF_u16.to_le_bytes());
        p[b * 100 + 2..b * 100 + 4].copy_from_slice(&az.to_le_bytes());
    }
    p[1200..1204].copy_from_slice(&micros.to_le_bytes());
    p[1204] = mode;
    p[1205] = model.packet_id();
    p
}

fn set_return(p: &mut [u8], block: usize, channel: usize, counts: u16, reflectivity: u8) {
    let o = block * 100 + 4 + 3 * channel;
    p[o..o + 2].copy_from_slice(&counts.to_le_bytes());
    p[o + 2] = reflectivity;
}

fn rows(scan: &DecodedScan) -> Vec<&[f32]> {
    scan.points.chunks_exact(POINT_COLUMNS).collect()
}

#[test]
fn one_vlp16_return_lands_where_the_manual_puts_it() {
    // standing still at 90°: laser 0 (−15°) of the first sequence, laser 1 (+1°) of the second
    let mut p = packet(VelodyneModel::Vlp16, 0x37, [9000; 12], 1_000);
    set_return(&mut p, 0, 0, 5000, 40); // 10 m
    set_return(&mut p, 0, 17, 2500, 7); // 5 m, second firing sequence of block 0
    set_return(&mut p, 3, 5, 10, 9); // 2 cm: under the minimum range, dropped
    let host = START + 0.0015;
    let scan = decode_scan(VelodyneModel::Vlp16, &p, &[host]).unwrap();
    assert_eq!(scan.len(), 2);
    assert_eq!(scan.host_stamp, host);
    assert!((scan.device_stamp - (START + 0.001)).abs() < 1e-9);
    let r = rows(&scan);
    let el = (-15.0_f64).to_radians();
    let offset = -0.04191 * el.tan(); // the laser's origin sits 11 mm above the centre
                                      // azimuth 90° clockwise from x: straight to the right (−y)
    assert!(f64::from(r[0][0]).abs() < 1e-6);
    assert!((f64::from(r[0][1]) + 10.0 * el.cos()).abs() < 1e-5);
    assert!((f64::from(r[0][2]) - (10.0 * el.sin() + offset)).abs() < 1e-5);
    assert_eq!(&r[0][3..], &[40.0, 0.0, 0.0, 0.0, RETURN_STRONGEST]);
    // second sequence: 55.296 + 2.304 µs later, next column, ring 8 of 16 (+1°)
    assert!((f64::from(r[1][4]) - 57.6e-6).abs() < 1e-9);
    assert_eq!((r[1][3], r[1][5], r[1][6]), (7.0, 1.0, 8.0));
}

#[test]
fn azimuths_are_interpolated_through_the_wrap() {
    // 0.2° per block from 359.9°: block 11 reads 2.1°; the second sequence of block 0 fires
    // half a block later, at 360.0° -> 0
    let az: [u16; 12] = std::array::from_fn(|b| ((35_990 + 20 * b) % 36_000) as u16);
    let mut p = packet(VelodyneModel::Vlp16, 0x37, az, 0);
    set_return(&mut p, 0, 16, 5000, 1);
    set_return(&mut p, 11, 0, 5000, 1);
    let scan = decode_scan(VelodyneModel::Vlp16, &p, &[START]).unwrap();
    let r = rows(&scan);
    assert!(r[0][1].abs() < 1e-6 && r[0][0] > 9.6); // straight ahead
    let bearing = f64::from(-r[1][1]).atan2(f64::from(r[1][0])).to_degrees();
    assert!((bearing - 2.1).abs() < 1e-4);
    assert_eq!((r[0][5], r[1][5]), (1.0, 22.0));
}

#[test]
fn dual_returns_pair_last_and_strongest_blocks() {
    let mut p = packet(VelodyneModel::Hdl32e, 0x39, [100; 12], 0);
    set_return(&mut p, 0, 3, 4000, 10); // last
    set_return(&mut p, 1, 3, 4000, 12); // strongest, the same return
    set_return(&mut p, 2, 4, 6000, 20); // last
    set_return(&mut p, 3, 4, 3000, 90); // strongest, nearer
    set_return(&mut p, 5, 6, 3000, 50); // strongest only
    let scan = decode_scan(VelodyneModel::Hdl32e, &p, &[START]).unwrap();
    let kinds: Vec<(f32, f32, f32)> = rows(&scan).iter().map(|r| (r[3], r[5], r[7])).collect();
    assert_eq!(
        kinds,
        [
            (12.0, 0.0, RETURN_BOTH),
            (20.0, 1.0, RETURN_LAST),
            (90.0, 1.0, RETURN_STRONGEST),
            (50.0, 2.0, RETURN_STRONGEST),
        ]
    );
}

#[test]
fn columns_continue_from_the_last_point_and_a_foreign_block_ends_a_packet() {
    let mut a = packet(VelodyneModel::Vlp16, 0x38, [0; 12], 0);
    set_return(&mut a, 4, 2, 1000, 1); // column 8
    let mut b = packet(VelodyneModel::Vlp16, 0x38, [0; 12], 1327);
    set_return(&mut b, 0, 0, 1000, 2); // column 9: one past the last point, not 24
    set_return(&mut b, 2, 0, 1000, 3);
    b[200..202].copy_from_slice(&0xDDFF_u16.to_le_bytes()); // block 2: nothing from here on
    let bytes = [a, b].concat();
    let scan = decode_scan(VelodyneModel::Vlp16, &bytes, &[START, START + 0.0013]).unwrap();
    let r = rows(&scan);
    assert_eq!(scan.len(), 2);
    assert_eq!((r[0][5], r[0][7], r[1][5]), (8.0, RETURN_LAST, 9.0));
    // times are from the last packet's device time: the first packet fired 1.327 ms before
    // (UNIX seconds in double resolve 0.24 µs)
    assert!((f64::from(r[0][4]) - (8.0 * 55.296e-6 + 2.0 * 2.304e-6 - 1.327e-3)).abs() < 1e-6);
}

#[test]
fn device_time_resolves_the_hour_from_the_host_clock() {
    let t = device_time(START + 10.0, 5_000_000);
    assert!((t - (START + 5.0)).abs() < 1e-9);
    // host just past the hour, packet stamped just before it
    let t = device_time(START + 1.0, 3_599_000_000);
    assert!((t - (START - 1.0)).abs() < 1e-9);
    // host just before the hour, packet just after it
    let t = device_time(START - 1.0, 1_000_000);
    assert!((t - (START + 1.0)).abs() < 1e-9);
    // a host before the epoch wraps to 32 bits and is not compared
    assert!((device_time(-5.3, 0) - 4_294_965_600.0).abs() < 1e-9);
    assert_eq!(device_time(1e19, 0), 3600.0);
}

#[test]
fn bad_input_is_an_error_naming_the_argument() {
    let p = packet(VelodyneModel::Vlp16, 0x37, [0; 12], 0);
    let dim = |r: Result<DecodedScan>| match r {
        Err(Error::Dimension { arg, .. }) => arg == "payloads",
        _ => false,
    };
    assert!(dim(decode_scan(VelodyneModel::Vlp16, &p[..1205], &[START])));
    assert!(dim(decode_scan(VelodyneModel::Vlp16, &p, &[START, START])));
    assert!(dim(decode_scan(VelodyneModel::Vlp16, &[], &[])));
    assert!(matches!(
        decode_scan(VelodyneModel::Vlp16, &p, &[f64::NAN]),
        Err(Error::NonFinite { .. })
    ));
    let err = decode_scan(VelodyneModel::Hdl32e, &p, &[START]).unwrap_err();
    assert!(err
        .to_string()
        .contains("packet 0 has model id 0x22, expected 0x21"));
    let mut q = p.clone();
    q[1204] = 0x40;
    let err = decode_scan(VelodyneModel::Vlp16, &q, &[START]).unwrap_err();
    assert!(err
        .to_string()
        .starts_with("payloads: packet 0 has return mode 0x40"));
}

#[test]
fn models_by_name_and_packet_id() {
    for m in VelodyneModel::ALL {
        assert_eq!(VelodyneModel::from_name(m.name()), Some(m));
        assert_eq!(VelodyneModel::from_packet_id(m.packet_id()), Some(m));
    }
    assert_eq!(VelodyneModel::from_packet_id(0x28), None);
    assert_eq!(VelodyneModel::from_name("VLP-32C"), None);
}

#[test]
fn zero_rotation_correction_leaves_every_table_entry_alone() {
    // the decoder's cos(a − b), sin(a − b) with b = 0 as it computes them, against cos a, sin a
    let (cos_b, sin_b) = (black_box(0.0_f32).cos(), black_box(0.0_f32).sin());
    for (i, &[c, s]) in rotation_table().cos_sin.iter().enumerate() {
        assert_eq!((c * cos_b + s * sin_b).to_bits(), c.to_bits(), "cos at {i}");
        assert_eq!((s * cos_b - c * sin_b).to_bits(), s.to_bits(), "sin at {i}");
    }
}

#[test]
fn azimuth_rounding_is_lroundf() {
    for a in [
        0.0_f32, 0.5, 1.5, 2.4999998, 35_999.5, 35_999.49, 36_000.0, 65_535.0, 70_123.7,
    ] {
        let expected = ((f64::from(a) + 36_000.0) as f32).round() as u32 % 36_000;
        assert_eq!(wrap_azimuth(a), expected as usize, "{a}");
    }
}

#[test]
fn packet_checks_find_the_first_problem() {
    let good = packet(VelodyneModel::Hdl32e, 0x37, [35_999; 12], 0);
    assert_eq!(packet_problem(&good, None), None);
    assert_eq!(packet_problem(&good, Some(0x21)), None);
    assert_eq!(
        packet_problem(&good, Some(0x22)),
        Some(PacketProblem::ModelId)
    );
    assert_eq!(
        packet_problem(&good[..1205], None),
        Some(PacketProblem::Length)
    );
    let mut lower = good.clone();
    lower[500..502].copy_from_slice(&0xDDFF_u16.to_le_bytes()); // HDL-64E lower block
    assert_eq!(packet_problem(&lower, None), None);
    let mut p = good.clone();
    p[1100] = 0; // block 11's flag, and an azimuth past a turn: the flag is found first
    p[2..4].copy_from_slice(&36_000_u16.to_le_bytes());
    assert_eq!(packet_problem(&p, None), Some(PacketProblem::BlockFlag));
    p[1100] = 0xFF;
    assert_eq!(packet_problem(&p, None), Some(PacketProblem::Azimuth));
    for (at, value) in [(1204, 0x36), (1205, 0x23)] {
        let mut p = good.clone();
        p[at] = value;
        assert_eq!(packet_problem(&p, None), Some(PacketProblem::FactoryBytes));
    }
    let mut vls = good.clone();
    vls[1205] = 0xA1; // known to velodyne-decoder (HDL-64E), not decoded here
    assert_eq!(packet_problem(&vls, None), None);
}

#[test]
fn a_stream_is_checked_against_the_last_model_that_passed() {
    let hdl = packet(VelodyneModel::Hdl32e, 0x37, [0; 12], 0);
    let vlp = packet(VelodyneModel::Vlp16, 0x39, [0; 12], 0);
    let mut broken_vlp = vlp.clone();
    broken_vlp[0] = 0;
    let data = [&hdl[..], &broken_vlp, &vlp, &hdl, &vlp[..100]].concat();
    let offsets: Vec<usize> = (0..5).map(|k| k * PACKET_SIZE).collect();
    let problems = stream_problems(&data, &offsets);
    assert_eq!(
        problems,
        [
            None,
            Some(PacketProblem::BlockFlag), // refused: the stream stays on the HDL-32E
            Some(PacketProblem::ModelId),
            None,
            Some(PacketProblem::Length), // runs past the end of the data
        ]
    );
    // a stream bound to the first packet's model: here the VLP-16
    assert_eq!(
        stream_problems(&data, &[2 * PACKET_SIZE, 0, usize::MAX]),
        [
            None,
            Some(PacketProblem::ModelId),
            Some(PacketProblem::Length)
        ]
    );
    let labels = PacketProblem::ALL.map(PacketProblem::label);
    assert_eq!(labels[1..4], ["block flag", "azimuth", "factory bytes"]);
}
