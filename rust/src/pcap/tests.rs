//! Hand-built captures through the record stream and the frame reader (parity with dpkt
//! itself on real, simulated and random captures is tested from Python,
//! `tests/test_pcap_records.py`).

use super::datagrams::frame_udp;
use super::ipv4::internet_checksum;
use super::*;
use crate::error::Error;

const T0: u32 = 1_415_644_617; // Nov 2014, UNIX s

/// Byte order and resolution of a capture.
#[derive(Clone, Copy)]
struct Format {
    big: bool,
    nanos: bool,
}

const MICROS_LE: Format = Format {
    big: false,
    nanos: false,
};

fn u32s(format: Format, values: &[u32]) -> Vec<u8> {
    values
        .iter()
        .flat_map(|v| {
            if format.big {
                v.to_be_bytes()
            } else {
                v.to_le_bytes()
            }
        })
        .collect()
}

fn file_header(format: Format, snaplen: u32, linktype: u32) -> Vec<u8> {
    let magic = if format.nanos {
        0xa1b2_3c4d
    } else {
        0xa1b2_c3d4
    };
    let mut h = u32s(format, &[magic]);
    let version = if format.big {
        [0, 2, 0, 4]
    } else {
        [2, 0, 4, 0]
    };
    h.extend(version);
    h.extend(u32s(format, &[0, 0, snaplen, linktype]));
    h
}

fn record(format: Format, sec: u32, frac: u32, frame: &[u8]) -> Vec<u8> {
    let n = frame.len() as u32;
    let mut r = u32s(format, &[sec, frac, n, n]);
    r.extend_from_slice(frame);
    r
}

/// The standard (big-endian) one's complement checksum of a header, RFC 1071.
fn rfc1071(b: &[u8]) -> u16 {
    let mut s: u32 = b
        .chunks(2)
        .map(|w| u32::from(w[0]) << 8 | u32::from(*w.get(1).unwrap_or(&0)))
        .sum();
    while s > 0xffff {
        s = (s >> 16) + (s & 0xffff);
    }
    !(s as u16)
}

/// An IPv4 packet (header of `words` × 4 bytes, options zero, protocol `proto`, flags/offset
/// `frag`) around a UDP datagram to `port` holding `payload`; checksum filled in.
fn ipv4(proto: u8, frag: u16, words: u8, port: u16, payload: &[u8]) -> Vec<u8> {
    let hl = usize::from(words) * 4;
    let total = hl + 8 + payload.len();
    let mut p = vec![0_u8; hl];
    p[0] = 0x40 | words;
    p[2..4].copy_from_slice(&(total as u16).to_be_bytes());
    p[6..8].copy_from_slice(&frag.to_be_bytes());
    p[8] = 64;
    p[9] = proto;
    p[12..16].copy_from_slice(&[192, 168, 1, 201]);
    p[16..20].copy_from_slice(&[255; 4]);
    for (k, b) in p[20..].iter_mut().enumerate() {
        *b = k as u8 + 1; // options, whatever they say
    }
    let sum = rfc1071(&p);
    p[10..12].copy_from_slice(&sum.to_be_bytes());
    p.extend_from_slice(&port.to_be_bytes());
    p.extend_from_slice(&port.to_be_bytes());
    p.extend_from_slice(&((8 + payload.len()) as u16).to_be_bytes());
    p.extend_from_slice(&[0, 0]);
    p.extend_from_slice(payload);
    p
}

fn udp4(port: u16, payload: &[u8]) -> Vec<u8> {
    ipv4(17, 0x4000, 5, port, payload)
}

fn ether(ty: u16, body: &[u8]) -> Vec<u8> {
    let mut f = vec![0xff; 6];
    f.extend_from_slice(&[0x60, 0x76, 0x88, 0x00, 0xa1, 0xb2]);
    f.extend_from_slice(&ty.to_be_bytes());
    f.extend_from_slice(body);
    f
}

fn capture(format: Format, linktype: u32, frames: &[(u32, u32, Vec<u8>)]) -> Vec<u8> {
    let mut data = file_header(format, 65_535, linktype);
    for (sec, frac, frame) in frames {
        data.extend(record(format, *sec, *frac, frame));
    }
    data
}

fn payloads<'a>(data: &'a [u8], d: &UdpDatagrams) -> Vec<&'a [u8]> {
    d.offsets
        .iter()
        .zip(&d.lengths)
        .map(|(&o, &n)| &data[o..o + n])
        .collect()
}

fn only(d: &UdpDatagrams, kind: Damage, count: usize) {
    for k in Damage::ALL {
        assert_eq!(d.count(k), if k == kind { count } else { 0 }, "{k:?}");
    }
}

#[test]
fn the_checksum_is_dpkts() {
    // dpkt's own test vector (`in_cksum` of bytes 0..14 is 51150 after its byte swap)
    let bytes: Vec<u8> = (0..15).collect();
    assert_eq!(internet_checksum(&bytes).swap_bytes(), 51150);
    // an intact header sums to zero, in either byte order of the words
    let p = udp4(2368, b"x");
    assert_eq!(internet_checksum(&p[..20]), 0);
    let mut bad = p[..20].to_vec();
    bad[8] ^= 1;
    assert_ne!(internet_checksum(&bad), 0);
    // the little-endian sum is the standard one with its bytes swapped, odd lengths included
    for n in [0, 1, 7, 19, 20] {
        assert_eq!(
            internet_checksum(&bad[..n]),
            rfc1071(&bad[..n]).swap_bytes(),
            "{n}"
        );
    }
}

#[test]
fn every_magic_gives_the_same_datagrams() {
    let frames = |nanos: bool| {
        let frac = |us: u32| if nanos { us * 1000 + 7 } else { us };
        vec![
            (T0, frac(1), ether(0x0800, &udp4(2368, &[1; 1206]))),
            (T0, frac(999_999), ether(0x0800, &udp4(8308, &[2; 512]))),
            (T0 + 1, frac(0), ether(0x0800, &udp4(2368, &[3; 3]))),
        ]
    };
    for big in [false, true] {
        for nanos in [false, true] {
            let data = capture(Format { big, nanos }, 1, &frames(nanos));
            let d = udp_datagrams(&data).unwrap();
            assert_eq!(d.records, 3);
            assert_eq!(d.linktype, 1);
            only(&d, Damage::RecordHeader, 0);
            assert_eq!(d.ports, [2368, 8308, 2368]);
            let p = payloads(&data, &d);
            assert_eq!(p, [&[1; 1206][..], &[2; 512][..], &[3; 3][..]]);
            let tick = if nanos { 1e-9 } else { 1e-6 };
            let frac = if nanos { 999_999_007.0 } else { 999_999.0 };
            assert_eq!(d.times[1], f64::from(T0) + frac * tick);
            assert_eq!(d.times[2], f64::from(T0 + 1));
        }
    }
}

#[test]
fn other_files_are_refused_naming_data() {
    let pcapng = [0x0a, 0x0d, 0x0d, 0x0a].repeat(8);
    for bad in [&b""[..], &b"\xd4\xc3\xb2\xa1"[..], &pcapng[..]] {
        match udp_datagrams(bad) {
            Err(Error::InvalidParameter { arg, reason }) => {
                assert_eq!(arg, "data");
                assert!(reason.contains("pcapng"), "{reason}");
            }
            other => panic!("{other:?}"),
        }
    }
    // a header alone is an empty capture
    let d = udp_datagrams(&file_header(MICROS_LE, 0, 1)).unwrap();
    assert!(d.is_empty() && d.records == 0);
}

#[test]
fn a_cut_record_ends_the_stream() {
    let mut data = capture(MICROS_LE, 1, &[(T0, 0, ether(0x0800, &udp4(1, b"ab")))]);
    let whole = data.clone();
    data.extend(record(MICROS_LE, T0, 5, &ether(0x0800, &udp4(1, b"cd"))));
    for cut in [whole.len() + 7, data.len() - 1] {
        let d = udp_datagrams(&data[..cut]).unwrap();
        assert_eq!((d.len(), d.records), (1, 2));
        only(&d, Damage::TruncatedRecord, 1);
    }
}

#[test]
fn garbage_between_records_costs_one_header() {
    let good = |k: u32| record(MICROS_LE, T0, k, &ether(0x0800, &udp4(9, &[k as u8; 40])));
    let mut data = file_header(MICROS_LE, 65_535, 1);
    data.extend(good(1));
    data.extend([0xee; 37]); // no plausible header starts in here
    data.extend(good(2));
    data.extend(good(3));
    let d = udp_datagrams(&data).unwrap();
    assert_eq!(d.len(), 3);
    assert_eq!(d.records, 4);
    only(&d, Damage::RecordHeader, 1);
    assert_eq!(payloads(&data, &d)[1], &[2; 40][..]);
    // the damage sits between the first datagram and the second; the garbage is a record
    assert_eq!(d.damaged, [(1, Damage::RecordHeader)]);
    assert_eq!(d.record_counts, [1, 3, 4]);
}

#[test]
fn a_lone_outlier_is_damage_and_a_confirmed_step_is_adopted() {
    let f = || ether(0x0800, &udp4(9, b"p"));
    // the second record's seconds are off by a day, its neighbours agree: skipped
    let data = capture(
        MICROS_LE,
        1,
        &[(T0, 0, f()), (T0 + 86_000, 0, f()), (T0 + 1, 0, f())],
    );
    let d = udp_datagrams(&data).unwrap();
    assert_eq!((d.records, d.len()), (3, 2));
    only(&d, Damage::RecordTimestamp, 1);
    // a step of 100 s that the next record confirms: every record kept
    let data = capture(
        MICROS_LE,
        1,
        &[
            (T0, 0, f()),
            (T0 + 1, 0, f()),
            (T0 + 100, 0, f()),
            (T0 + 101, 0, f()),
        ],
    );
    let d = udp_datagrams(&data).unwrap();
    assert_eq!(d.len(), 4);
    only(&d, Damage::RecordTimestamp, 0);
    // a jump in the last record: nothing confirms it
    let data = capture(
        MICROS_LE,
        1,
        &[(T0, 0, f()), (T0 + 1, 0, f()), (T0 + 100, 0, f())],
    );
    let d = udp_datagrams(&data).unwrap();
    assert_eq!(d.len(), 2);
    only(&d, Damage::RecordTimestamp, 1);
    // the first record is the outlier of the first three
    let data = capture(
        MICROS_LE,
        1,
        &[(T0 - 500, 0, f()), (T0, 0, f()), (T0 + 1, 0, f())],
    );
    let d = udp_datagrams(&data).unwrap();
    assert_eq!(d.times, [f64::from(T0), f64::from(T0 + 1)]);
    only(&d, Damage::RecordTimestamp, 1);
}

#[test]
fn a_header_beyond_the_hour_window_resynchronises() {
    // seconds two hours back: not a plausible header after T0, so "record header"
    let f = || ether(0x0800, &udp4(9, b"p"));
    let data = capture(
        MICROS_LE,
        1,
        &[(T0, 0, f()), (T0 - 7200, 0, f()), (T0 + 1, 0, f())],
    );
    let d = udp_datagrams(&data).unwrap();
    assert_eq!((d.records, d.len()), (3, 2));
    only(&d, Damage::RecordHeader, 1);
}

fn link(linktype: u32, frame: &[u8]) -> Result<Option<(u16, usize, usize)>, Damage> {
    frame_udp(linktype, frame)
}

#[test]
fn ethernet_vlan_mpls_isl_and_sll_lead_to_the_datagram() {
    let ip = udp4(2368, b"velodyne");
    let at = |f: &[u8]| Ok(Some((2368, f.len() - 8, 8)));
    let plain = ether(0x0800, &ip);
    assert_eq!(link(1, &plain), at(&plain));
    let mut tagged = vec![0x00, 0x05, 0x08, 0x00];
    tagged.extend_from_slice(&ip);
    let one = ether(0x8100, &tagged);
    assert_eq!(link(1, &one), at(&one));
    let mut two = vec![0x00, 0x06, 0x81, 0x00];
    two.extend_from_slice(&tagged);
    let qinq = ether(0x88a8, &two);
    assert_eq!(link(1, &qinq), at(&qinq));
    // after two tags naming 0x8100, dpkt's second pass reads two more: a fifth is not read
    let mut three = vec![0x00, 0x07, 0x81, 0x00];
    three.extend_from_slice(&two);
    let three = ether(0x8100, &three);
    assert_eq!(link(1, &three), at(&three));
    let mut five = [0x00, 0x08, 0x81, 0x00].repeat(3);
    five.extend_from_slice(&two);
    assert_eq!(link(1, &ether(0x8100, &five)), Ok(None));
    // a tag naming MPLS: labels read by the second pass
    let mut to_mpls = vec![0x00, 0x05, 0x88, 0x47, 0x00, 0x01, 0x01, 0x40];
    to_mpls.extend_from_slice(&ip);
    let to_mpls = ether(0x8100, &to_mpls);
    assert_eq!(link(1, &to_mpls), at(&to_mpls));
    assert_eq!(
        link(1, &ether(0x8100, &[0x00, 0x05, 0x88, 0x47, 0x00])),
        Err(Damage::LinkIpHeader)
    );
    let mut mpls = vec![0x00, 0x01, 0x01, 0x40]; // bottom of stack
    mpls.extend_from_slice(&ip);
    let labelled = ether(0x8847, &mpls);
    assert_eq!(link(1, &labelled), at(&labelled));
    let mut isl = vec![0x01, 0x00, 0x0c, 0x00, 0x00];
    isl.extend([0; 21]);
    isl.extend_from_slice(&plain);
    assert_eq!(link(1, &isl), at(&isl));
    let mut sll = vec![0; 14];
    sll.extend_from_slice(&0x0800_u16.to_be_bytes());
    sll.extend_from_slice(&ip);
    assert_eq!(link(113, &sll), at(&sll));
    for raw in [101, 12] {
        assert_eq!(link(raw, &ip), at(&ip));
    }
    assert_eq!(link(228, &ip), Ok(None)); // LINKTYPE_IPV4 is not read
}

#[test]
fn other_protocols_are_skipped_and_cut_headers_are_damage() {
    let ip = udp4(2368, b"velodyne");
    for ty in [0x0806, 0x86dd, 0x6558, 0x9999, 0x05dd] {
        assert_eq!(link(1, &ether(ty, &ip)), Ok(None), "{ty:#x}");
    }
    assert_eq!(
        link(1, &ether(0x0800, &ipv4(6, 0, 5, 80, b"tcp"))),
        Ok(None)
    );
    // a later fragment is kept as bytes; a first fragment is read as a whole datagram
    assert_eq!(
        link(1, &ether(0x0800, &ipv4(17, 0x0010, 5, 9, b"x"))),
        Ok(None)
    );
    let first = ether(0x0800, &ipv4(17, 0x2000, 5, 9, b"x"));
    assert_eq!(link(1, &first), Ok(Some((9, first.len() - 1, 1))));
    // a cut IPv4 header: kept as bytes behind Ethernet and SLL, damage as a raw packet
    assert_eq!(link(1, &ether(0x0800, &ip[..19])), Ok(None));
    assert_eq!(link(101, &ip[..19]), Err(Damage::LinkIpHeader));
    let mut v6 = ip.clone();
    v6[0] = 0x60; // the header length nibble is 0
    assert_eq!(link(101, &v6), Err(Damage::LinkIpHeader));
    assert_eq!(
        link(1, &ether(0x0800, &ip)[..13]),
        Err(Damage::LinkIpHeader)
    );
    assert_eq!(link(113, &[0; 15]), Err(Damage::LinkIpHeader));
    assert_eq!(
        link(1, &ether(0x8100, &[0, 1, 8])),
        Err(Damage::LinkIpHeader)
    );
    assert_eq!(
        link(1, &ether(0x8847, &[0, 1, 0])),
        Err(Damage::LinkIpHeader)
    );
    // a label stack with nothing after it (dpkt: IndexError)
    assert_eq!(
        link(1, &ether(0x8847, &[0, 1, 1, 64])),
        Err(Damage::LinkIpHeader)
    );
    let mut isl = vec![0x03, 0x00, 0x0c, 0x00, 0x00];
    isl.extend([0; 20]);
    assert_eq!(link(1, &isl), Err(Damage::LinkIpHeader));
    // 802.3: Novell raw IPX, LLC (SNAP, IP, IPX, STP)
    assert_eq!(link(1, &ether(40, &[0xff; 31])), Err(Damage::LinkIpHeader));
    assert_eq!(link(1, &ether(40, &[0xff; 32])), Ok(None));
    assert_eq!(link(1, &ether(2, &[0xaa; 40])), Err(Damage::LinkIpHeader));
    assert_eq!(link(1, &ether(8, &[0xaa; 40])), Ok(None));
    let mut llc_ip = vec![0x06, 0x06, 0x03];
    llc_ip.extend_from_slice(&ip);
    assert_eq!(link(1, &ether(22, &llc_ip)), Err(Damage::LinkIpHeader));
    assert_eq!(link(1, &ether(23, &llc_ip)), Ok(None));
    assert_eq!(link(1, &ether(37, &[0x42; 40])), Err(Damage::LinkIpHeader));
    assert_eq!(link(1, &ether(0, &ip)), Ok(None));
}

#[test]
fn checksums_lengths_and_options() {
    let ip = udp4(2368, b"velodyne");
    let mut bad = ip.clone();
    bad[10] ^= 0x40;
    assert_eq!(link(101, &bad), Err(Damage::IpChecksum));
    let mut bad = ip.clone();
    bad[25] = 0; // UDP length 16 -> 0
    assert_eq!(link(101, &bad), Err(Damage::UdpLength));
    // options are part of the header (and of its checksum)
    let opts = ipv4(17, 0, 7, 77, b"abc");
    assert_eq!(link(101, &opts), Ok(Some((77, 36, 3))));
    let mut bad = opts.clone();
    bad[25] ^= 1;
    assert_eq!(link(101, &bad), Err(Damage::IpChecksum));
    // Ethernet padding after the total length is not payload; total length 0 runs to the end
    let mut padded = ether(0x0800, &ip);
    padded.extend([0; 6]);
    assert_eq!(link(1, &padded), Ok(Some((2368, 14 + 28, 8))));
    // a total length shorter than the headers leaves no datagram
    let mut short = ip.clone();
    short[2..4].copy_from_slice(&24_u16.to_be_bytes());
    let sum = rfc1071(&{
        let mut h = short[..20].to_vec();
        h[10..12].copy_from_slice(&[0, 0]);
        h
    });
    short[10..12].copy_from_slice(&sum.to_be_bytes());
    assert_eq!(link(101, &short), Ok(None));
    let mut zero = short.clone();
    zero[2..4].copy_from_slice(&[0, 0]);
    let sum = rfc1071(&{
        let mut h = zero[..20].to_vec();
        h[10..12].copy_from_slice(&[0, 0]);
        h
    });
    zero[10..12].copy_from_slice(&sum.to_be_bytes());
    assert_eq!(link(101, &zero), Ok(Some((2368, 28, 8))));
}

#[test]
fn frame_damage_is_counted_per_record() {
    let mut bad = udp4(5, b"x");
    bad[11] ^= 1;
    let data = capture(
        MICROS_LE,
        101,
        &[
            (T0, 0, udp4(5, b"a")),
            (T0, 1, bad),
            (T0, 2, vec![0x45; 10]),
        ],
    );
    let d = udp_datagrams(&data).unwrap();
    assert_eq!((d.records, d.len()), (3, 1));
    assert_eq!(d.count(Damage::IpChecksum), 1);
    assert_eq!(d.count(Damage::LinkIpHeader), 1);
    assert_eq!(
        d.damaged,
        [(1, Damage::IpChecksum), (1, Damage::LinkIpHeader)]
    );
    // a cut last record: counted after every datagram
    let cut = &data[..data.len() - 3];
    let d = udp_datagrams(cut).unwrap();
    assert_eq!(d.damaged.last(), Some(&(1, Damage::TruncatedRecord)));
    assert_eq!((d.record_counts.as_slice(), d.records), (&[1][..], 3));
    assert_eq!(Damage::ALL.map(Damage::label)[3], "link/IP header");
}
