//! libpcap captures read to their UDP/IPv4 datagrams in one pass, exactly as usvfast's
//! Python reader read them with dpkt 1.9 (the oracle of `tests/test_pcap_records.py`): the
//! same records, timestamps, ports and payload bytes, the same damage counted under the same
//! labels.
//!
//! A libpcap file (tcpdump's format, `pcap-savefile(5)`) is a 24-byte header (magic,
//! version, snap length, link type) and records, each a 16-byte header (seconds, µs or ns by
//! the magic, captured length, original length) and the captured frame:
//!
//! ```text
//! a1b2c3d4 (µs) or a1b23c4d (ns), in the writer's byte order | 2 | 4 | 0 | 0 | snaplen | linktype
//! [ ts_sec | ts_frac | incl_len | orig_len ] frame (incl_len bytes) ...
//! ```
//!
//! [`records`] walks the records (resynchronising after damage), [`link`] takes a frame's
//! link layers off down to its IPv4 header, [`ipv4`] reads the IPv4 and UDP headers, and
//! [`datagrams`] ties them into [`udp_datagrams`]. pcapng files are refused. Where dpkt itself
//! fails with an exception its callers never caught (an MPLS label stack with nothing after
//! it: IndexError), the frame is read as if dpkt had raised its `UnpackError`.

pub mod datagrams;
pub mod ipv4;
pub mod link;
pub mod records;

pub use datagrams::{udp_datagrams, UdpDatagrams};
pub use records::{Record, Records};

/// Why a record or frame was skipped as damaged; [`Damage::label`] is the reader's name.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Damage {
    /// An implausible record header (the stream resynchronises after it).
    RecordHeader,
    /// A record cut by the end of the file (the stream ends there).
    TruncatedRecord,
    /// A record whose seconds disagree with both neighbours.
    RecordTimestamp,
    /// A link-layer or IPv4 header cut short or malformed.
    LinkIpHeader,
    /// An IPv4 header whose checksum does not sum to zero.
    IpChecksum,
    /// A UDP length field that disagrees with the datagram.
    UdpLength,
}

impl Damage {
    /// Every kind, in label order of the reader's record pass.
    pub const ALL: [Damage; 6] = [
        Self::RecordHeader,
        Self::TruncatedRecord,
        Self::RecordTimestamp,
        Self::LinkIpHeader,
        Self::IpChecksum,
        Self::UdpLength,
    ];

    /// The reader's label of this damage ("record header", ..., "UDP length").
    #[must_use]
    pub fn label(self) -> &'static str {
        match self {
            Self::RecordHeader => "record header",
            Self::TruncatedRecord => "truncated record",
            Self::RecordTimestamp => "record timestamp",
            Self::LinkIpHeader => "link/IP header",
            Self::IpChecksum => "IP checksum",
            Self::UdpLength => "UDP length",
        }
    }
}

#[cfg(test)]
mod tests;
