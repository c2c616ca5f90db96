//! The libpcap record stream (see the [module doc](super)): the file header, then record by
//! record with resynchronisation after a damaged header and the neighbour-judged timestamp
//! rule.

use super::Damage;
use crate::error::{Error, Result};

/// Largest frame a record may hold, bytes (libpcap's `MAXIMUM_SNAPLEN`); also the snap length
/// of a file whose header says 0.
pub const MAX_SNAPLEN: u32 = 262_144;
/// Size of the file header, bytes.
pub const FILE_HEADER_SIZE: usize = 24;
/// Size of a record header, bytes.
pub const RECORD_HEADER_SIZE: usize = 16;

/// One readable record: its timestamp and where its frame lies in the file.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Record {
    /// Capture time, UNIX s: the header's seconds plus its fraction (µs or ns by the magic).
    pub time: f64,
    /// Offset of the frame's first byte in the file.
    pub start: usize,
    /// Captured length of the frame, bytes.
    pub len: usize,
}

/// True when `sec` can follow `reference` in one capture stream (1 s of reordering back, up
/// to a minute of silence forward).
fn close_in_time(reference: u32, sec: u32) -> bool {
    (-1..=60).contains(&(i64::from(sec) - i64::from(reference)))
}

/// The records of a libpcap file, in file order, counting what it skips.
///
/// A record whose header is implausible (captured length 0, beyond the snap length or the
/// original length, original length beyond [`MAX_SNAPLEN`], a fraction of a second ≥ 1 s, a
/// time an hour before or a day after the last accepted record) is counted as
/// [`Damage::RecordHeader`] and the stream resynchronises on the next position holding a
/// plausible header followed by another plausible header (or the end of the file). A record
/// cut by the end of the file is counted as [`Damage::TruncatedRecord`] and ends the stream.
///
/// A header's seconds are judged by both neighbours: a record whose seconds disagree with
/// the previous accepted record while the next record agrees with it is the single outlier
/// (a damaged `ts_sec`), skipped as [`Damage::RecordTimestamp`], and the reference time stays;
/// a jump the next record confirms is a real clock step and is adopted (an unconfirmed jump,
/// as in the last record, is damage). The first record is judged by the next two.
#[derive(Clone, Debug)]
pub struct Records<'a> {
    data: &'a [u8],
    big_endian: bool,
    /// Fraction units per second: 10⁶ (µs magic) or 10⁹ (ns magic).
    per_second: u32,
    tick: f64,
    snaplen: u32,
    linktype: u32,
    pos: usize,
    last_sec: Option<u32>,
    done: bool,
    records: usize,
    damaged: Vec<Damage>,
}

impl<'a> Records<'a> {
    /// Reads the file header of `data` (a whole libpcap capture). Fails with
    /// [`Error::InvalidParameter`] naming `data` when it is shorter than a file header or its
    /// magic is not one of libpcap's four (µs or ns, either byte order); pcapng is refused.
    pub fn new(data: &'a [u8]) -> Result<Self> {
        let magic = data.get(..4).filter(|_| data.len() >= FILE_HEADER_SIZE);
        let (big_endian, per_second, tick) = match magic {
            Some([0xd4, 0xc3, 0xb2, 0xa1]) => (false, 1_000_000, 1e-6),
            Some([0xa1, 0xb2, 0xc3, 0xd4]) => (true, 1_000_000, 1e-6),
            Some([0x4d, 0x3c, 0xb2, 0xa1]) => (false, 1_000_000_000, 1e-9),
            Some([0xa1, 0xb2, 0x3c, 0x4d]) => (true, 1_000_000_000, 1e-9),
            _ => {
                return Err(Error::param(
                    "data",
                    "not a libpcap file (pcapng is not supported)",
                ))
            }
        };
        let mut out = Self {
            data,
            big_endian,
            per_second,
            tick,
            snaplen: 0,
            linktype: 0,
            pos: FILE_HEADER_SIZE,
            last_sec: None,
            done: false,
            records: 0,
            damaged: Vec::new(),
        };
        let snaplen = out.u32_at(16);
        out.snaplen = if snaplen == 0 {
            MAX_SNAPLEN
        } else {
            snaplen.min(MAX_SNAPLEN)
        };
        out.linktype = out.u32_at(20);
        Ok(out)
    }

    /// The file's link type (LINKTYPE_* number of its header).
    #[must_use]
    pub fn linktype(&self) -> u32 {
        self.linktype
    }

    /// Records seen so far, damaged ones included.
    #[must_use]
    pub fn records(&self) -> usize {
        self.records
    }

    /// The damaged records skipped so far, in file order (record kinds only).
    #[must_use]
    pub fn damaged(&self) -> &[Damage] {
        &self.damaged
    }

    fn u32_at(&self, pos: usize) -> u32 {
        let b = [
            self.data[pos],
            self.data[pos + 1],
            self.data[pos + 2],
            self.data[pos + 3],
        ];
        if self.big_endian {
            u32::from_be_bytes(b)
        } else {
            u32::from_le_bytes(b)
        }
    }

    /// (seconds, fraction, captured length) of the header at `pos`, when a plausible header
    /// fits there; `reference` (seconds of the last accepted record) bounds the seconds.
    fn plausible(&self, pos: usize, reference: Option<u32>) -> Option<(u32, u32, usize)> {
        if pos + RECORD_HEADER_SIZE > self.data.len() {
            return None;
        }
        let (sec, frac) = (self.u32_at(pos), self.u32_at(pos + 4));
        let (incl, orig) = (self.u32_at(pos + 8), self.u32_at(pos + 12));
        if incl == 0 || incl > self.snaplen || incl > orig || orig > MAX_SNAPLEN {
            return None;
        }
        if frac >= self.per_second {
            return None;
        }
        let near = |r: u32| (-3600..=86_400).contains(&(i64::from(sec) - i64::from(r)));
        if !reference.is_none_or(near) {
            return None;
        }
        Some((sec, frac, incl as usize))
    }

    /// Seconds of the header at `pos` when it is plausible on its own.
    fn header_sec(&self, pos: usize) -> Option<u32> {
        self.plausible(pos, None).map(|h| h.0)
    }

    /// The first position from `start` holding a plausible header followed by another
    /// plausible header or the end of the file; the end of the file when there is none.
    fn resync(&self, start: usize, reference: Option<u32>) -> usize {
        let n = self.data.len();
        let mut pos = start;
        while pos + RECORD_HEADER_SIZE <= n {
            if let Some((_, _, incl)) = self.plausible(pos, reference) {
                let next = pos + RECORD_HEADER_SIZE + incl;
                if next == n || self.plausible(next, reference).is_some() {
                    return pos;
                }
            }
            pos += 1;
        }
        n
    }

    fn count(&mut self, damage: Damage) {
        self.damaged.push(damage);
    }
}

impl Iterator for Records<'_> {
    type Item = Record;

    fn next(&mut self) -> Option<Record> {
        let n = self.data.len();
        while !self.done && self.pos < n {
            let pos = self.pos;
            if pos + RECORD_HEADER_SIZE > n {
                self.records += 1;
                self.count(Damage::TruncatedRecord);
                self.done = true;
                return None;
            }
            let Some((sec, frac, incl)) = self.plausible(pos, self.last_sec) else {
                self.records += 1;
                self.count(Damage::RecordHeader);
                self.pos = self.resync(pos + 1, self.last_sec);
                continue;
            };
            self.records += 1;
            let next = pos + RECORD_HEADER_SIZE + incl;
            if next > n {
                self.count(Damage::TruncatedRecord);
                self.done = true;
                return None;
            }
            let next_sec = self.header_sec(next);
            let judge = match (self.last_sec, next_sec) {
                // the first record: judged by the next two (is it or the next one the outlier?)
                (None, Some(next_sec)) => {
                    let after = next + RECORD_HEADER_SIZE + self.u32_at(next + 8) as usize;
                    match self.header_sec(after) {
                        Some(after_sec) if !close_in_time(next_sec, after_sec) => None,
                        _ => Some(next_sec),
                    }
                }
                (last, _) => last,
            };
            if let Some(judge) = judge {
                let confirmed = next_sec.is_some_and(|s| !close_in_time(judge, s));
                if !close_in_time(judge, sec) && !confirmed {
                    // the one outlier between agreeing neighbours (or a jump nothing confirms)
                    self.count(Damage::RecordTimestamp);
                    self.pos = next;
                    continue;
                }
            }
            self.last_sec = Some(sec);
            self.pos = next;
            return Some(Record {
                time: f64::from(sec) + f64::from(frac) * self.tick,
                start: pos + RECORD_HEADER_SIZE,
                len: incl,
            });
        }
        None
    }
}
