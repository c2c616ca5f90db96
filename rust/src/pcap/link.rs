//! Link layers down to the IPv4 header, as dpkt 1.9 (`dpkt.ethernet.Ethernet`,
//! `dpkt.sll.SLL`, `dpkt.ip.IP`) takes a frame apart: where its IPv4 header starts, whether
//! the frame holds something else, or whether dpkt would raise `UnpackError` (the reader's
//! "link/IP header" damage).
//!
//! dpkt decodes each layer by its type field and keeps a layer it cannot decode as raw bytes
//! when the failure happens inside a dispatch (an unknown type or a short inner header is not
//! an error); only the headers it reads outside a dispatch make the frame fail: the Ethernet
//! header, 802.1Q tags, MPLS labels, a Cisco ISL header, a Novell raw 802.3 IPX header, an
//! 802.2 LLC header and the IP, IPX or STP header it names. An IPv4 header is any buffer of
//! 20 bytes or more whose header-length nibble is at least 5; the version nibble is not read.
//! An Ethernet II payload left as raw bytes is decoded once more, as dpkt's constructor does.

/// Where a frame's link layers lead.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Link {
    /// An IPv4 header starts at this offset of the frame (and runs to the frame's end).
    Ipv4(usize),
    /// Anything else (another network protocol, an unknown type, a layer dpkt keeps as bytes).
    Other,
    /// A header dpkt reads outside a dispatch is cut short or malformed.
    Broken,
}

const ETH_HEADER: usize = 14;
const ETH_TYPE_IP: u16 = 0x0800;
const ETH_TYPE_IP6: u16 = 0x86DD;
const ETH_TYPE_8021Q: u16 = 0x8100;
const ETH_TYPE_QINQ: [u16; 4] = [ETH_TYPE_8021Q, 0x88A8, 0x9100, 0x9200];
const ETH_TYPE_MPLS: [u16; 2] = [0x8847, 0x8848];
const ETH_TYPE_TEB: u16 = 0x6558;
/// The Ethernet types dpkt decodes (`Ethernet._typesw`); other types stay raw bytes.
const ETH_DECODED: [u16; 11] = [
    0x00BB, 0x0800, 0x0806, 0x2000, 0x2004, 0x6558, 0x8137, 0x86DD, 0x880B, 0x8864, 0x88A2,
];
/// Largest 802.3 length field; a larger type field names an Ethernet II payload.
const ETH_LEN_MAX: u16 = 1500;
const VLAN_TAG: usize = 4;
const MPLS_LABEL: usize = 4;
/// dpkt reads at most this many MPLS labels.
const MPLS_MAX_LABELS: usize = 24;
const ISL_HEADER: usize = 26;
const IPX_HEADER: usize = 30;
const STP_HEADER: usize = 35;
const LLC_HEADER: usize = 3;
const SNAP_HEADER: usize = 5;
const SLL_HEADER: usize = 16;
/// Smallest IPv4 header, bytes.
pub const IPV4_MIN_HEADER: usize = 20;

/// LINKTYPE_ETHERNET.
pub const LINKTYPE_ETHERNET: u32 = 1;
/// LINKTYPE_RAW (and its old number, 12 on OpenBSD's DLT_RAW): the frame is an IP packet.
pub const LINKTYPE_RAW: [u32; 2] = [101, 12];
/// LINKTYPE_LINUX_SLL: Linux "cooked" capture.
pub const LINKTYPE_LINUX_SLL: u32 = 113;

fn be16(b: &[u8], at: usize) -> u16 {
    u16::from_be_bytes([b[at], b[at + 1]])
}

/// True when dpkt parses `b` as an IPv4 header: 20 bytes or more, header length ≥ 5 words.
#[must_use]
pub fn ipv4_header_ok(b: &[u8]) -> bool {
    b.len() >= IPV4_MIN_HEADER && b[0] & 0x0f >= 5
}

/// The link layers of `frame`, captured with link type `linktype`: Ethernet
/// ([`LINKTYPE_ETHERNET`]), raw IP ([`LINKTYPE_RAW`]) or Linux SLL ([`LINKTYPE_LINUX_SLL`]);
/// other link types are [`Link::Other`].
#[must_use]
pub fn link_layers(linktype: u32, frame: &[u8]) -> Link {
    match linktype {
        LINKTYPE_ETHERNET => ethernet(frame),
        t if LINKTYPE_RAW.contains(&t) => {
            if ipv4_header_ok(frame) {
                Link::Ipv4(0)
            } else {
                Link::Broken
            }
        }
        LINKTYPE_LINUX_SLL => {
            if frame.len() < SLL_HEADER {
                Link::Broken
            } else if be16(frame, SLL_HEADER - 2) == ETH_TYPE_IP
                && ipv4_header_ok(&frame[SLL_HEADER..])
            {
                Link::Ipv4(SLL_HEADER)
            } else {
                Link::Other // the protocol's own failures stay inside SLL's dispatch
            }
        }
        _ => Link::Other,
    }
}

/// An Ethernet frame: Ethernet II with 802.1Q / QinQ tags or MPLS labels, Cisco ISL
/// encapsulation (an Ethernet frame after a 26-byte header), Novell raw 802.3, 802.3 with an
/// 802.2 LLC header.
///
/// dpkt's `Ethernet(frame)` decodes an Ethernet II payload, and when that leaves raw bytes it
/// decodes those once more from where the first pass stopped, with the type the first pass
/// ended on: tags naming another tag type, or MPLS, read a second group of tags or labels.
fn ethernet(frame: &[u8]) -> Link {
    let mut at = 0;
    let ty = loop {
        let buf = &frame[at..];
        if buf.len() < ETH_HEADER {
            return Link::Broken;
        }
        let ty = be16(buf, 12);
        if ty > ETH_LEN_MAX {
            break ty;
        }
        if buf.starts_with(&[0x01, 0x00, 0x0c, 0x00, 0x00])
            || buf.starts_with(&[0x03, 0x00, 0x0c, 0x00, 0x00])
        {
            // Cisco ISL: its header, then an Ethernet frame
            if buf.len() < ISL_HEADER {
                return Link::Broken;
            }
            at += ISL_HEADER;
            continue;
        }
        let body = &buf[ETH_HEADER..];
        if body.starts_with(&[0xff, 0xff]) {
            // Novell raw 802.3: an IPX header after the two 0xff
            return if body.len() - 2 >= IPX_HEADER {
                Link::Other
            } else {
                Link::Broken
            };
        }
        if ty == 0 {
            return Link::Other; // "unknown type": dpkt looks type 0 up and keeps the bytes
        }
        return llc(&body[..body.len().min(usize::from(ty))]);
    };
    let (next, data) = ethernet_payload(frame, at + ETH_HEADER, ty, ty);
    let data = match data {
        Payload::Bytes(rest) if rest < frame.len() => ethernet_payload(frame, rest, next, ty).1,
        data => data,
    };
    match data {
        Payload::Ipv4(at) => Link::Ipv4(at),
        Payload::Bytes(_) | Payload::Other => Link::Other,
        Payload::Broken => Link::Broken,
    }
}

/// What one decoding pass over an Ethernet II payload leaves.
enum Payload {
    /// An IPv4 header at this offset.
    Ipv4(usize),
    /// Raw bytes from this offset (no decoder for the type, or its decoder failed).
    Bytes(usize),
    /// Another protocol, decoded.
    Other,
    /// A tag or label cut short.
    Broken,
}

/// One pass of dpkt's Ethernet payload decoding from `at`, starting from type `next` (the
/// frame's type field is `ty`): the type it ends on and what it leaves.
fn ethernet_payload(frame: &[u8], mut at: usize, mut next: u16, ty: u16) -> (u16, Payload) {
    if ETH_TYPE_QINQ.contains(&next) {
        // up to two 802.1Q tags; a second one only after a tag naming 0x8100
        for _ in 0..2 {
            if frame.len() - at < VLAN_TAG {
                return (next, Payload::Broken);
            }
            next = be16(frame, at + 2);
            at += VLAN_TAG;
            if next != ETH_TYPE_8021Q {
                break;
            }
        }
    } else if ETH_TYPE_MPLS.contains(&next) {
        // labels up to the bottom of the stack (its S bit), at most 24
        for _ in 0..MPLS_MAX_LABELS {
            if frame.len() - at < MPLS_LABEL {
                return (next, Payload::Broken);
            }
            let bottom = frame[at + 2] & 1 == 1;
            at += MPLS_LABEL;
            if bottom {
                break;
            }
        }
        // dpkt guesses what follows the stack from its first byte (and fails with IndexError
        // when nothing follows: read here as a broken header)
        let Some(&first) = frame.get(at) else {
            return (next, Payload::Broken);
        };
        if first == 0x45 {
            next = ETH_TYPE_IP;
        } else if first & 0xf0 == 0x60 {
            next = ETH_TYPE_IP6;
        } else if frame.len() - at >= ETH_HEADER {
            next = ETH_TYPE_TEB; // pseudowire Ethernet: decoded, never IPv4 at this level
        }
    }
    // a tag naming type 0 leaves dpkt on the frame's type
    let payload = if next == 0 { ty } else { next };
    let data = if payload == ETH_TYPE_IP && ipv4_header_ok(&frame[at..]) {
        Payload::Ipv4(at)
    } else if payload == ETH_TYPE_IP || !ETH_DECODED.contains(&payload) {
        Payload::Bytes(at)
    } else {
        // decoded as another protocol, or kept as bytes when its decoder fails: a second pass
        // from the same type reads the same, so which one it is does not matter
        Payload::Other
    };
    (next, data)
}

/// An 802.2 LLC header (and SNAP) of an 802.3 frame: never IPv4 at the Ethernet level, but
/// dpkt reads the header it names (IP, IPX, STP) outside a dispatch.
fn llc(buf: &[u8]) -> Link {
    if buf.len() < LLC_HEADER {
        return Link::Broken;
    }
    let body = &buf[LLC_HEADER..];
    let whole = match (buf[0], buf[1]) {
        (0xaa, 0xaa) => body.len() >= SNAP_HEADER, // SNAP: OUI and type, then a dispatch
        (0x06, _) => ipv4_header_ok(body),
        (0x10 | 0xe0, _) => body.len() >= IPX_HEADER,
        (0x42, _) => body.len() >= STP_HEADER,
        _ => true,
    };
    if whole {
        Link::Other
    } else {
        Link::Broken
    }
}
