//! Check stage 1: header, length, CRC and the section directory; the
//! [`Directory`] the later stages read their sections through.

use crate::math::source::{LeF32, LeF64};
use crate::table::bytes::{rd_u16, rd_u32};
use crate::table::crc::CRC;
use crate::table::error::TableError;
use crate::table::layout::{
    entry_field, header_field, CRC_LEN, DIR_ENTRY_LEN, EXTENSION_BASE, HEADER_LEN, MAGIC, MAX_SECTIONS,
    VERSION,
};
use crate::table::section::{Section, N_KNOWN};

#[derive(Clone, Copy)]
pub(crate) struct Entry {
    pub(crate) kind: u16,
    pub(crate) count: u32,
    pub(crate) offset: u32,
    pub(crate) len: u32,
}

impl Entry {
    pub(crate) fn range(&self) -> (usize, usize) {
        let start = self.offset as usize;
        (start, start.saturating_add(self.len as usize))
    }
}

pub(crate) fn read_entry(bytes: &[u8], header_len: usize, idx: usize) -> Result<Entry, TableError> {
    let e = idx
        .checked_mul(DIR_ENTRY_LEN)
        .and_then(|x| x.checked_add(header_len))
        .ok_or(TableError::DirectoryOutOfBounds)?;
    let oob = TableError::DirectoryOutOfBounds;
    let kind = rd_u16(bytes, e + entry_field::KIND).ok_or(oob)?;
    let reserved = rd_u16(bytes, e + entry_field::RESERVED).ok_or(oob)?;
    if reserved != 0 {
        return Err(TableError::EntryReserved { entry: idx });
    }
    Ok(Entry {
        kind,
        count: rd_u32(bytes, e + entry_field::COUNT).ok_or(oob)?,
        offset: rd_u32(bytes, e + entry_field::OFFSET).ok_or(oob)?,
        len: rd_u32(bytes, e + entry_field::BYTE_LEN).ok_or(oob)?,
    })
}

/// Read the header's total length (for a table at the start of a larger
/// region, e.g. flash): checks magic and version only.
pub fn peek_total_len(bytes: &[u8]) -> Result<usize, TableError> {
    if bytes.len() < HEADER_LEN {
        return Err(TableError::TooShort { len: bytes.len() });
    }
    if bytes.get(header_field::MAGIC..header_field::MAGIC + MAGIC.len()) != Some(&MAGIC[..]) {
        return Err(TableError::BadMagic);
    }
    let version = rd_u16(bytes, header_field::VERSION).ok_or(TableError::TooShort { len: bytes.len() })?;
    if version != VERSION {
        return Err(TableError::UnsupportedVersion { found: version });
    }
    Ok(rd_u32(bytes, header_field::TOTAL_LEN).ok_or(TableError::TooShort { len: bytes.len() })? as usize)
}

/// The validated directory: where each known section is (extensions
/// skipped), and the section readers the later stages use.
pub(crate) struct Directory<'a> {
    bytes: &'a [u8],
    found: [Option<Entry>; N_KNOWN],
}

/// Header (magic, version, header length, reserved), total length, CRC,
/// section count, then every directory entry (kind known or an extension,
/// aligned, inside the data area, no overlap, no duplicate, byte length =
/// count × element size).
pub(crate) fn directory(bytes: &[u8]) -> Result<Directory<'_>, TableError> {
    let total = peek_total_len(bytes)?;
    let short = TableError::TooShort { len: bytes.len() };
    let header_len = usize::from(rd_u16(bytes, header_field::HEADER_LEN).ok_or(short)?);
    let count = rd_u16(bytes, header_field::SECTION_COUNT).ok_or(short)?;
    if header_len < HEADER_LEN || header_len % 8 != 0 || rd_u16(bytes, header_field::RESERVED) != Some(0) {
        return Err(TableError::BadHeader);
    }
    if total != bytes.len() {
        return Err(TableError::LengthMismatch {
            header: total as u32,
            actual: bytes.len(),
        });
    }
    let body_len = total.checked_sub(CRC_LEN).ok_or(short)?;
    let body = bytes.get(..body_len).ok_or(short)?;
    let stored = rd_u32(bytes, body_len).ok_or(short)?;
    let computed = CRC.checksum(body);
    if stored != computed {
        return Err(TableError::Crc { stored, computed });
    }
    let n_sec = usize::from(count);
    if n_sec == 0 || n_sec > MAX_SECTIONS {
        return Err(TableError::SectionCount { count });
    }
    let dir_end = header_len
        .checked_add(n_sec * DIR_ENTRY_LEN)
        .ok_or(TableError::DirectoryOutOfBounds)?;
    if dir_end > body_len {
        return Err(TableError::DirectoryOutOfBounds);
    }

    let mut found: [Option<Entry>; N_KNOWN] = [None; N_KNOWN];
    for idx in 0..n_sec {
        let e = read_entry(bytes, header_len, idx)?;
        let known = Section::from_code(e.kind);
        if known.is_none() && e.kind < EXTENSION_BASE {
            return Err(TableError::UnknownSection { kind: e.kind });
        }
        if e.offset % 8 != 0 {
            return Err(TableError::Misaligned {
                kind: e.kind,
                offset: e.offset,
            });
        }
        let (start, end) = e.range();
        if start < dir_end || end > body_len {
            return Err(TableError::OutOfBounds { kind: e.kind });
        }
        for prev in 0..idx {
            let p = read_entry(bytes, header_len, prev)?;
            let (ps, pe) = p.range();
            if start < pe && ps < end {
                return Err(TableError::Overlap {
                    kind: e.kind,
                    other: p.kind,
                });
            }
        }
        if let Some(section) = known {
            let slot = found
                .get_mut(section.slot())
                .ok_or(TableError::UnknownSection { kind: e.kind })?;
            if slot.is_some() {
                return Err(TableError::DuplicateSection { section });
            }
            if (e.count as usize).checked_mul(section.element_len()) != Some(e.len as usize) {
                return Err(TableError::SectionLength { section });
            }
            *slot = Some(e);
        }
    }
    Ok(Directory { bytes, found })
}

impl<'a> Directory<'a> {
    /// The directory entry of `section`, if present.
    pub(crate) fn entry(&self, section: Section) -> Option<Entry> {
        self.found.get(section.slot()).copied().flatten()
    }

    /// The bytes of `section`; missing: [`TableError::MissingSection`].
    pub(crate) fn bytes_of(&self, section: Section) -> Result<&'a [u8], TableError> {
        let e = self
            .entry(section)
            .ok_or(TableError::MissingSection { section })?;
        let (start, end) = e.range();
        self.bytes
            .get(start..end)
            .ok_or(TableError::OutOfBounds { kind: e.kind })
    }

    /// `section` as f64 values, every one finite.
    pub(crate) fn f64s(&self, section: Section) -> Result<LeF64<'a>, TableError> {
        let v = LeF64::new(self.bytes_of(section)?).ok_or(TableError::SectionLength { section })?;
        if let Some(index) = v.iter().position(|x| !x.is_finite()) {
            return Err(TableError::NotFinite { section, index });
        }
        Ok(v)
    }

    /// `section` as f32 values, every one finite.
    pub(crate) fn f32s(&self, section: Section) -> Result<LeF32<'a>, TableError> {
        let v = LeF32::new(self.bytes_of(section)?).ok_or(TableError::SectionLength { section })?;
        if let Some(index) = v.iter().position(|x| !x.is_finite()) {
            return Err(TableError::NotFinite { section, index });
        }
        Ok(v)
    }

    /// An empty slice of the table (for empty views).
    pub(crate) fn empty(&self) -> &'a [u8] {
        self.bytes.get(..0).unwrap_or(&[])
    }
}
