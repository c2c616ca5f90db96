//! One pass over a capture: every record's frame through its link layers, IPv4 and UDP
//! headers (see the [module doc](super)).

use super::ipv4::{ipv4_udp, Ipv4};
use super::link::{link_layers, Link};
use super::records::Records;
use super::Damage;
use crate::error::Result;

/// The UDP/IPv4 datagrams of a capture, in file order, and what was skipped on the way.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct UdpDatagrams {
    /// Capture time of each datagram's record, UNIX s.
    pub times: Vec<f64>,
    /// Destination port of each datagram.
    pub ports: Vec<u16>,
    /// Offset of each datagram's payload in the capture, bytes.
    pub offsets: Vec<usize>,
    /// Length of each datagram's payload, bytes.
    pub lengths: Vec<usize>,
    /// Records seen up to each datagram's record (included), damaged ones included.
    pub record_counts: Vec<usize>,
    /// Records seen, damaged ones included.
    pub records: usize,
    /// Damaged records and frames in file order, each with the number of datagrams before it.
    pub damaged: Vec<(usize, Damage)>,
    /// The capture's link type (LINKTYPE_* number).
    pub linktype: u32,
}

impl UdpDatagrams {
    /// Number of datagrams.
    #[must_use]
    pub fn len(&self) -> usize {
        self.times.len()
    }

    /// True when the capture holds no readable UDP/IPv4 datagram.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.times.is_empty()
    }

    /// Count of one kind of damage.
    #[must_use]
    pub fn count(&self, kind: Damage) -> usize {
        self.damaged.iter().filter(|(_, k)| *k == kind).count()
    }
}

/// What one frame (captured with link type `linktype`) holds: a UDP/IPv4 datagram (port,
/// payload offset in the frame, length), nothing for the reader (`Ok(None)`: another
/// protocol, another link type), or damage ([`Damage::LinkIpHeader`],
/// [`Damage::IpChecksum`], [`Damage::UdpLength`]).
pub fn frame_udp(
    linktype: u32,
    frame: &[u8],
) -> std::result::Result<Option<(u16, usize, usize)>, Damage> {
    let at = match link_layers(linktype, frame) {
        Link::Ipv4(at) => at,
        Link::Other => return Ok(None),
        Link::Broken => return Err(Damage::LinkIpHeader),
    };
    match ipv4_udp(&frame[at..]) {
        Ipv4::Udp { port, offset, len } => Ok(Some((port, at + offset, len))),
        Ipv4::Other => Ok(None),
        Ipv4::Damaged(kind) => Err(kind),
    }
}

/// Every UDP/IPv4 datagram of the libpcap capture `data` (the whole file), with the records
/// seen and the damage skipped ([`Records`] for the records, [`frame_udp`] for the frames),
/// both placed among the datagrams (a reader handing the datagrams on one by one can count as
/// it goes).
///
/// Fails with [`crate::Error::InvalidParameter`] naming `data` when it is not a libpcap file
/// (pcapng included); damage inside the file is counted, never an error.
pub fn udp_datagrams(data: &[u8]) -> Result<UdpDatagrams> {
    let mut records = Records::new(data)?;
    let linktype = records.linktype();
    let mut out = UdpDatagrams {
        linktype,
        ..UdpDatagrams::default()
    };
    let mut logged = 0;
    while let Some(record) = records.next() {
        let before = out.len();
        for &kind in &records.damaged()[logged..] {
            out.damaged.push((before, kind));
        }
        logged = records.damaged().len();
        let frame = &data[record.start..record.start + record.len];
        match frame_udp(linktype, frame) {
            Ok(Some((port, offset, len))) => {
                out.times.push(record.time);
                out.ports.push(port);
                out.offsets.push(record.start + offset);
                out.lengths.push(len);
                out.record_counts.push(records.records());
            }
            Ok(None) => {}
            Err(kind) => out.damaged.push((before, kind)),
        }
    }
    let end = out.len();
    for &kind in &records.damaged()[logged..] {
        out.damaged.push((end, kind));
    }
    out.records = records.records();
    Ok(out)
}
