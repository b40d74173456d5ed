//! The table's trailing CRC-32 (ISO-HDLC, the zlib/PNG CRC).

use crate::table::layout::CRC_LEN;

/// How the CRC is computed: byte by byte through a 256-entry table on the
/// host; bit by bit on a bare-metal target, where that table would take
/// 1 KiB of flash (of a streaming image's 64 KiB) for what runs once per
/// chunk on arrival and once over a table at start, never on the servo tick.
/// The same CRC either way (the `crc` crate's implementations).
#[cfg(not(target_os = "none"))]
type CrcImpl = crc::Table<1>;
#[cfg(target_os = "none")]
type CrcImpl = crc::NoTable;

pub(crate) const CRC: crc::Crc<u32, CrcImpl> = crc::Crc::<u32, CrcImpl>::new(&crc::CRC_32_ISO_HDLC);

/// The CRC-32 (ISO-HDLC) a table stores over `body` (every byte before the CRC).
pub fn crc32(body: &[u8]) -> u32 {
    CRC.checksum(body)
}

/// Recompute and store the trailing CRC of `bytes` (a whole table, CRC
/// included) in place; `false` if `bytes` is shorter than the CRC. For tools
/// and tests that edit a table on purpose (fuzzing behind the checksum).
pub fn reseal(bytes: &mut [u8]) -> bool {
    let Some(body_len) = bytes.len().checked_sub(CRC_LEN) else {
        return false;
    };
    let crc = crc32(bytes.get(..body_len).unwrap_or(&[]));
    match bytes.get_mut(body_len..) {
        Some(tail) => {
            tail.copy_from_slice(&crc.to_le_bytes());
            true
        }
        None => false,
    }
}
