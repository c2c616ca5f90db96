//! An IPv4 header and the UDP datagram it carries, read as dpkt 1.9 (`dpkt.ip.IP`,
//! `dpkt.udp.UDP`) reads them, with the two checks the reader adds: the header checksum
//! (RFC 791 §3.1: the one's complement sum of the header as stored, options included, is
//! 0xffff) and the UDP length field against the datagram dpkt takes out (RFC 768).

use super::link::IPV4_MIN_HEADER;
use super::Damage;

const IP_PROTO_UDP: u8 = 17;
const UDP_HEADER: usize = 8;
/// Fragment offset bits of the flags/offset field.
const FRAGMENT_OFFSET: u16 = 0x1fff;

/// What an IPv4 packet holds for the reader.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Ipv4 {
    /// A UDP datagram: its destination port and its payload (offset from the start of the
    /// IPv4 header, length), bytes.
    Udp {
        port: u16,
        offset: usize,
        len: usize,
    },
    /// Not a UDP datagram dpkt takes out (another protocol, a later fragment, a UDP header
    /// cut short).
    Other,
    /// A broken header: [`Damage::IpChecksum`] or [`Damage::UdpLength`].
    Damaged(Damage),
}

fn be16(b: &[u8], at: usize) -> u16 {
    u16::from_be_bytes([b[at], b[at + 1]])
}

/// The Internet checksum of `b` as dpkt's `in_cksum` computes it (16-bit little-endian
/// words, an odd last byte added alone, the carries folded twice, complemented): 0 when `b`
/// is a header holding its own intact checksum.
#[must_use]
pub fn internet_checksum(b: &[u8]) -> u16 {
    let mut words = b.chunks_exact(2);
    let mut s: u64 = words
        .by_ref()
        .map(|w| u64::from(u16::from_le_bytes([w[0], w[1]])))
        .sum();
    if let [last] = words.remainder() {
        s += u64::from(*last);
    }
    s = (s >> 16) + (s & 0xffff);
    s += s >> 16;
    // complemented, the low 16 bits (dpkt then swaps the bytes: zero stays zero)
    !(s as u16)
}

/// The packet `b` (an IPv4 header and whatever the frame holds after it; the caller checked
/// [`super::link::ipv4_header_ok`]).
///
/// The datagram runs from the end of the header (IHL × 4, cut at the end of `b`) to the total
/// length field (to the end of `b` when that field is 0, as after segmentation offload; cut at
/// the end of `b`). It is UDP when the protocol is 17, the fragment offset 0 and it holds 8
/// bytes or more (a first fragment is read as a whole datagram). The checksum is checked
/// first, over the header as captured; then the UDP length field must equal the datagram's
/// length.
#[must_use]
pub fn ipv4_udp(b: &[u8]) -> Ipv4 {
    debug_assert!(b.len() >= IPV4_MIN_HEADER);
    let n = b.len();
    let header = (usize::from(b[0] & 0x0f) * 4).min(n);
    let total = usize::from(be16(b, 2));
    let end = if total == 0 { n } else { total.min(n) };
    let datagram = end.saturating_sub(header);
    if internet_checksum(&b[..header]) != 0 {
        return Ipv4::Damaged(Damage::IpChecksum);
    }
    let udp = b[9] == IP_PROTO_UDP && be16(b, 6) & FRAGMENT_OFFSET == 0 && datagram >= UDP_HEADER;
    if !udp {
        return Ipv4::Other;
    }
    if usize::from(be16(b, header + 4)) != datagram {
        return Ipv4::Damaged(Damage::UdpLength);
    }
    Ipv4::Udp {
        port: be16(b, header + 2),
        offset: header + UDP_HEADER,
        len: datagram - UDP_HEADER,
    }
}
