//! The program file: one planned program, the firmware tables of its paths
//! in order, with where each came from in the source.
//!
//! Little-endian, offsets from the start of the file:
//!
//! ```text
//! header (HEADER_LEN = 40)
//!   0  8  MAGIC "FLPPROG\0"
//!   8  2  VERSION (1)
//!  10  2  reserved, 0
//!  12  4  entry count E
//!  16  4  piece count P (over all entries)
//!  20  4  total length of the file, CRC included
//!  24  4  offset of the warnings text (right after the pieces)
//!  28  4  length of the warnings text, bytes (UTF-8, one warning a line)
//!  32  4  servo period the tables were planned for, ns (> 0)
//!  36  4  reserved, 0
//! E entries (ENTRY_LEN = 32 each)
//!   0  1  kind: 1 feed path, 2 rapid, 3 program stop (M0/M1: no table)
//!   1  3  reserved, 0
//!   4  4  first source line
//!   8  4  last source line
//!  12  4  index of its first piece
//!  16  4  its piece count (0 for a stop)
//!  20  4  offset of its firmware table (0 for a stop)
//!  24  4  length of its firmware table (0 for a stop)
//!  28  4  reserved, 0
//! P pieces (PIECE_LEN = 16 each): the moves of each path, in order
//!   0  8  arc length where the move ends on its path, mm (f64)
//!   8  4  source line of the move
//!  12  4  reserved, 0
//! the warnings text (the reader's and the path builder's, for the run's summary)
//! the tables, each starting at a multiple of TABLE_ALIGN (zero padding)
//! CRC-32 (ISO-HDLC, as the tables' own) over every byte before it
//! ```
//!
//! [`ProgramFile::parse`] checks everything before anything runs: the magic,
//! version, lengths and CRC; every entry's kind, line range and pieces
//! (increasing arc lengths ending at the table's path length, lines inside
//! the entry's range); every table by [`Table::parse`]. [`ProgramFile::encode`]
//! parses its own output before returning it, as the table encoder does.

use firmware_core::table::crc32;
use firmware_core::{Table, TableError};

/// The first 8 bytes.
pub const MAGIC: [u8; 8] = *b"FLPPROG\0";
/// The format version.
pub const VERSION: u16 = 1;
/// Header length, bytes.
pub const HEADER_LEN: usize = 40;
/// Entry length, bytes.
pub const ENTRY_LEN: usize = 32;
/// Piece length, bytes.
pub const PIECE_LEN: usize = 16;
/// Tables start at multiples of this, bytes.
pub const TABLE_ALIGN: usize = 8;
/// CRC length, bytes.
pub const CRC_LEN: usize = 4;
/// Relative tolerance of the last piece's arc length against the table's
/// path length.
const LENGTH_TOL: f64 = 1e-9;

/// What an entry is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum EntryKind {
    /// A feed path (G1/G2/G3/G5.2/G6.2 moves).
    Feed = 1,
    /// A rapid (G0).
    Rapid = 2,
    /// A program stop (M0/M1): no motion, no table.
    Stop = 3,
}

impl EntryKind {
    fn from_code(c: u8) -> Option<EntryKind> {
        match c {
            1 => Some(EntryKind::Feed),
            2 => Some(EntryKind::Rapid),
            3 => Some(EntryKind::Stop),
            _ => None,
        }
    }
}

/// One move of a path: where it ends and its source line.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct FilePiece {
    /// Arc length where the move ends on its path, mm.
    pub s_end_mm: f64,
    /// Source line.
    pub line: u32,
}

/// One entry: a planned path or a stop.
#[derive(Debug, Clone, PartialEq)]
pub struct Entry {
    /// Feed, rapid or stop.
    pub kind: EntryKind,
    /// First source line.
    pub first_line: u32,
    /// Last source line.
    pub last_line: u32,
    /// The moves (empty for a stop).
    pub pieces: Vec<FilePiece>,
    /// The firmware table (empty for a stop).
    pub table: Vec<u8>,
}

/// A program file's content.
#[derive(Debug, Clone, PartialEq)]
pub struct ProgramFile {
    /// In program order.
    pub entries: Vec<Entry>,
    /// Warnings of the planning (one per item, no newlines inside).
    pub warnings: Vec<String>,
    /// The servo period the tables were planned for, ns (the feed caps at
    /// curvature jumps depend on it: run them at this period).
    pub servo_period_ns: u32,
}

/// Why bytes are not a usable program file (exit code 3).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum ProgramFileError {
    /// Shorter than a header and a CRC.
    #[error("program file of {len} bytes is too short")]
    TooShort {
        /// Its length.
        len: usize,
    },
    /// Not the magic.
    #[error("not a program file (no FLPPROG magic)")]
    Magic,
    /// Another version.
    #[error("program file version {found}, this build reads {VERSION}")]
    Version {
        /// Found.
        found: u16,
    },
    /// Lengths that do not fit.
    #[error("program file length: {why}")]
    Length {
        /// What.
        why: String,
    },
    /// The CRC does not match.
    #[error("program file CRC mismatch: stored {stored:08x}, computed {computed:08x} (the file is corrupt)")]
    Crc {
        /// Stored.
        stored: u32,
        /// Computed.
        computed: u32,
    },
    /// An entry that does not fit.
    #[error("program file entry {index}: {why}")]
    Entry {
        /// Entry index.
        index: usize,
        /// What.
        why: String,
    },
    /// An entry's table is refused by the firmware's parser.
    #[error("program file entry {index} (LINE {first_line}..{last_line}): table rejected: {reason}")]
    Table {
        /// Entry index.
        index: usize,
        /// Its first line.
        first_line: u32,
        /// Its last line.
        last_line: u32,
        /// The firmware's reason.
        reason: TableError,
    },
}

fn u32_at(b: &[u8], at: usize) -> u32 {
    b.get(at..at + 4)
        .and_then(|s| s.try_into().ok())
        .map_or(0, u32::from_le_bytes)
}

fn u16_at(b: &[u8], at: usize) -> u16 {
    b.get(at..at + 2)
        .and_then(|s| s.try_into().ok())
        .map_or(0, u16::from_le_bytes)
}

fn f64_at(b: &[u8], at: usize) -> f64 {
    b.get(at..at + 8)
        .and_then(|s| s.try_into().ok())
        .map_or(f64::NAN, f64::from_le_bytes)
}

fn len_u32(n: usize, what: &str) -> Result<u32, ProgramFileError> {
    u32::try_from(n).map_err(|_| ProgramFileError::Length {
        why: format!("{what} {n} does not fit in 32 bits"),
    })
}

impl ProgramFile {
    /// True when `bytes` start with the program file's magic (the table's
    /// own magic is different).
    pub fn is_program(bytes: &[u8]) -> bool {
        bytes.starts_with(&MAGIC)
    }

    /// The bytes of this program file, checked by [`ProgramFile::parse`].
    pub fn encode(&self) -> Result<Vec<u8>, ProgramFileError> {
        let e = self.entries.len();
        let p: usize = self.entries.iter().map(|x| x.pieces.len()).sum();
        let warnings: String = self
            .warnings
            .iter()
            .map(|w| format!("{}\n", w.replace('\n', " ")))
            .collect();
        let warnings_at = HEADER_LEN + e * ENTRY_LEN + p * PIECE_LEN;
        let mut at = warnings_at + warnings.len();
        let mut offsets = Vec::with_capacity(e);
        for x in &self.entries {
            if x.table.is_empty() {
                offsets.push(0);
            } else {
                at = at.div_ceil(TABLE_ALIGN) * TABLE_ALIGN;
                offsets.push(at);
                at += x.table.len();
            }
        }
        let total = at + CRC_LEN;
        let mut out = vec![0u8; total];
        out[..8].copy_from_slice(&MAGIC);
        out[8..10].copy_from_slice(&VERSION.to_le_bytes());
        out[12..16].copy_from_slice(&len_u32(e, "entry count")?.to_le_bytes());
        out[16..20].copy_from_slice(&len_u32(p, "piece count")?.to_le_bytes());
        out[20..24].copy_from_slice(&len_u32(total, "file length")?.to_le_bytes());
        out[24..28].copy_from_slice(&len_u32(warnings_at, "warnings offset")?.to_le_bytes());
        out[28..32].copy_from_slice(&len_u32(warnings.len(), "warnings length")?.to_le_bytes());
        out[32..36].copy_from_slice(&self.servo_period_ns.to_le_bytes());
        out[warnings_at..warnings_at + warnings.len()].copy_from_slice(warnings.as_bytes());
        let mut piece = 0usize;
        for (i, (x, &off)) in self.entries.iter().zip(&offsets).enumerate() {
            let b = HEADER_LEN + i * ENTRY_LEN;
            out[b] = x.kind as u8;
            out[b + 4..b + 8].copy_from_slice(&x.first_line.to_le_bytes());
            out[b + 8..b + 12].copy_from_slice(&x.last_line.to_le_bytes());
            out[b + 12..b + 16].copy_from_slice(&len_u32(piece, "piece index")?.to_le_bytes());
            out[b + 16..b + 20].copy_from_slice(&len_u32(x.pieces.len(), "piece count")?.to_le_bytes());
            out[b + 20..b + 24].copy_from_slice(&len_u32(off, "table offset")?.to_le_bytes());
            out[b + 24..b + 28].copy_from_slice(&len_u32(x.table.len(), "table length")?.to_le_bytes());
            for pc in &x.pieces {
                let q = HEADER_LEN + e * ENTRY_LEN + piece * PIECE_LEN;
                out[q..q + 8].copy_from_slice(&pc.s_end_mm.to_le_bytes());
                out[q + 8..q + 12].copy_from_slice(&pc.line.to_le_bytes());
                piece += 1;
            }
            out[off..off + x.table.len()].copy_from_slice(&x.table);
        }
        let crc = crc32(&out[..total - CRC_LEN]);
        out[total - CRC_LEN..].copy_from_slice(&crc.to_le_bytes());
        let back = ProgramFile::parse(&out)?;
        if &back != self {
            return Err(ProgramFileError::Length {
                why: "the encoded file does not read back as written".into(),
            });
        }
        Ok(out)
    }

    /// Read and check a program file (see the module docs).
    pub fn parse(bytes: &[u8]) -> Result<ProgramFile, ProgramFileError> {
        let n = bytes.len();
        if n < HEADER_LEN + CRC_LEN {
            if n >= MAGIC.len() && !Self::is_program(bytes) {
                return Err(ProgramFileError::Magic);
            }
            return Err(ProgramFileError::TooShort { len: n });
        }
        if !Self::is_program(bytes) {
            return Err(ProgramFileError::Magic);
        }
        let version = u16_at(bytes, 8);
        if version != VERSION {
            return Err(ProgramFileError::Version { found: version });
        }
        let total = u32_at(bytes, 20) as usize;
        if total != n {
            return Err(ProgramFileError::Length {
                why: format!("the header says {total} bytes, the file has {n}"),
            });
        }
        let stored = u32_at(bytes, n - CRC_LEN);
        let computed = crc32(&bytes[..n - CRC_LEN]);
        if stored != computed {
            return Err(ProgramFileError::Crc { stored, computed });
        }
        let servo_period_ns = u32_at(bytes, 32);
        if servo_period_ns == 0 {
            return Err(ProgramFileError::Length {
                why: "the servo period is 0 ns".into(),
            });
        }
        let e = u32_at(bytes, 12) as usize;
        let p = u32_at(bytes, 16) as usize;
        let data_start = e
            .checked_mul(ENTRY_LEN)
            .and_then(|a| p.checked_mul(PIECE_LEN).and_then(|b| a.checked_add(b)))
            .and_then(|a| a.checked_add(HEADER_LEN))
            .filter(|&d| d <= n - CRC_LEN)
            .ok_or_else(|| ProgramFileError::Length {
                why: format!("{e} entries and {p} pieces do not fit in {n} bytes"),
            })?;
        let pieces_at = HEADER_LEN + e * ENTRY_LEN;
        let (w_at, w_len) = (u32_at(bytes, 24) as usize, u32_at(bytes, 28) as usize);
        if w_at != data_start || w_len > n - CRC_LEN - data_start {
            return Err(ProgramFileError::Length {
                why: format!("warnings text at {w_at}+{w_len}, expected at {data_start} inside the file"),
            });
        }
        let warnings = std::str::from_utf8(&bytes[w_at..w_at + w_len])
            .map_err(|_| ProgramFileError::Length {
                why: "the warnings text is not UTF-8".into(),
            })?
            .lines()
            .map(str::to_string)
            .collect();
        let data_start = data_start + w_len;
        let mut entries = Vec::with_capacity(e);
        let mut next_piece = 0usize;
        let mut data_end = data_start;
        for index in 0..e {
            let b = HEADER_LEN + index * ENTRY_LEN;
            let bad = |why: String| ProgramFileError::Entry { index, why };
            let kind =
                EntryKind::from_code(bytes[b]).ok_or_else(|| bad(format!("unknown kind {}", bytes[b])))?;
            let (first_line, last_line) = (u32_at(bytes, b + 4), u32_at(bytes, b + 8));
            let (p0, pc) = (u32_at(bytes, b + 12) as usize, u32_at(bytes, b + 16) as usize);
            let (off, len) = (u32_at(bytes, b + 20) as usize, u32_at(bytes, b + 24) as usize);
            if first_line > last_line {
                return Err(bad(format!("line range {first_line}..{last_line} is reversed")));
            }
            if p0 != next_piece || p0.checked_add(pc).is_none_or(|end| end > p) {
                return Err(bad(format!(
                    "pieces {p0}+{pc} do not follow the previous entry's in {p}"
                )));
            }
            next_piece = p0 + pc;
            let pieces: Vec<FilePiece> = (p0..p0 + pc)
                .map(|k| FilePiece {
                    s_end_mm: f64_at(bytes, pieces_at + k * PIECE_LEN),
                    line: u32_at(bytes, pieces_at + k * PIECE_LEN + 8),
                })
                .collect();
            if kind == EntryKind::Stop {
                if pc != 0 || len != 0 || off != 0 {
                    return Err(bad("a stop has no pieces and no table".into()));
                }
                entries.push(Entry {
                    kind,
                    first_line,
                    last_line,
                    pieces,
                    table: Vec::new(),
                });
                continue;
            }
            if pc == 0 {
                return Err(bad("a path without pieces".into()));
            }
            if off < data_end
                || off % TABLE_ALIGN != 0
                || off.checked_add(len).is_none_or(|end| end > n - CRC_LEN)
            {
                return Err(bad(format!(
                    "table at {off}+{len} is outside the table area or overlaps"
                )));
            }
            data_end = off + len;
            let table = &bytes[off..off + len];
            let t = Table::parse(table).map_err(|reason| ProgramFileError::Table {
                index,
                first_line,
                last_line,
                reason,
            })?;
            let length = t.path_length_mm();
            let mut prev = 0.0;
            for (k, piece) in pieces.iter().enumerate() {
                if !(piece.s_end_mm.is_finite() && piece.s_end_mm > prev) {
                    return Err(bad(format!(
                        "piece {k} ends at s = {} mm, not after {prev}",
                        piece.s_end_mm
                    )));
                }
                if !(first_line..=last_line).contains(&piece.line) {
                    return Err(bad(format!(
                        "piece {k}'s line {} is outside {first_line}..{last_line}",
                        piece.line
                    )));
                }
                prev = piece.s_end_mm;
            }
            if (prev - length).abs() > LENGTH_TOL * length.max(1.0) {
                return Err(bad(format!(
                    "the pieces end at {prev} mm, the table's path at {length} mm"
                )));
            }
            entries.push(Entry {
                kind,
                first_line,
                last_line,
                pieces,
                table: table.to_vec(),
            });
        }
        if next_piece != p {
            return Err(ProgramFileError::Length {
                why: format!("{p} pieces stated, {next_piece} used"),
            });
        }
        Ok(ProgramFile {
            entries,
            warnings,
            servo_period_ns,
        })
    }
}
