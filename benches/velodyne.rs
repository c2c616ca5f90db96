//! Criterion benchmark of the Velodyne packet decoder: one VLP-16 rotation at 600 rpm (76
//! packets of strongest returns), every channel returning (28,800 points) and one in eight.
use criterion::{criterion_group, criterion_main, Criterion};
use std::hint::black_box;
use usvfast_core::velodyne::{decode_scan, VelodyneModel, PACKET_SIZE};

/// 76 packets of a steady spin from azimuth 0; channel `c` of packet `p` returns when
/// `(p + c) % every == 0`, at 1–60 m.
fn rotation(every: usize) -> (Vec<u8>, Vec<f64>) {
    let mut bytes = Vec::with_capacity(76 * PACKET_SIZE);
    let mut times = Vec::with_capacity(76);
    for p in 0..76_usize {
        let mut pkt = vec![0_u8; PACKET_SIZE];
        for b in 0..12 {
            let o = b * 100;
            pkt[o..o + 2].copy_from_slice(&0xEEFF_u16.to_le_bytes());
            let az = ((p * 12 + b) * 40 % 36_000) as u16;
            pkt[o + 2..o + 4].copy_from_slice(&az.to_le_bytes());
            for c in 0..32 {
                if (p + b + c) % every == 0 {
                    let d = (500 + (p * 7919 + b * 104_729 + c * 1299) % 29_500) as u16;
                    pkt[o + 4 + 3 * c..o + 6 + 3 * c].copy_from_slice(&d.to_le_bytes());
                    pkt[o + 6 + 3 * c] = (c * 7) as u8;
                }
            }
        }
        let micros = (p * 1327) as u32;
        pkt[1200..1204].copy_from_slice(&micros.to_le_bytes());
        pkt[1204] = 0x37;
        pkt[1205] = 0x22;
        bytes.extend_from_slice(&pkt);
        times.push(1_686_909_600.0 + p as f64 * 1.327e-3);
    }
    (bytes, times)
}

fn bench_decode(c: &mut Criterion) {
    let mut g = c.benchmark_group("velodyne_vlp16_rotation");
    for (name, every) in [("dense", 1), ("sparse", 8)] {
        let (bytes, times) = rotation(every);
        g.bench_function(name, |b| {
            b.iter(|| decode_scan(VelodyneModel::Vlp16, black_box(&bytes), &times).unwrap())
        });
    }
    g.finish();
}

criterion_group!(benches, bench_decode);
criterion_main!(benches);
