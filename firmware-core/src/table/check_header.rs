//! Check stage 1: header, length, CRC and the section directory.

use crate::table::bytes::{rd_u16, rd_u32};
use crate::table::error::TableError;
use crate::table::layout::{entry_field, header_field};
use crate::table::layout::{DIR_ENTRY_LEN, HEADER_LEN, MAGIC, VERSION};

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
