//! The table's trailing CRC-32 (ISO-HDLC, the zlib/PNG CRC).

use crate::table::layout::CRC_LEN;

pub(crate) const CRC: crc::Crc<u32> = crc::Crc::<u32>::new(&crc::CRC_32_ISO_HDLC);

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
