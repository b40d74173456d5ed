#!/usr/bin/env python3
"""Wraps a plan table in the board's link frame (boards/stm32f4/src/link.rs).

Frame: magic b"FTBL", u32 LE table length, the table, u32 LE CRC-32
(ISO-HDLC, zlib's crc32) of the table bytes. The board checks the frame,
then parses the table, before anything moves.

Usage: frame-table.py TABLE.bin OUT        (OUT: a file, or a serial device)

To a board on /dev/ttyUSB0 (the link runs at 115,200 baud, 8N1):
    stty -F /dev/ttyUSB0 115200 raw -echo
    python3 frame-table.py table.bin /dev/ttyUSB0
"""
import struct
import sys
import zlib

MAGIC = b"FTBL"
RAM_BUFFER = 96 * 1024  # boards/stm32f4/src/config.rs TABLE_BUF_LEN


def frame(table: bytes) -> bytes:
    return MAGIC + struct.pack("<I", len(table)) + table + struct.pack("<I", zlib.crc32(table))


def main() -> int:
    if len(sys.argv) != 3:
        print(__doc__, file=sys.stderr)
        return 2
    with open(sys.argv[1], "rb") as f:
        table = f.read()
    if len(table) > RAM_BUFFER:
        print(f"frame-table: {len(table)} bytes do not fit the board's {RAM_BUFFER}-byte buffer "
              "(build the table in with --features baked-table instead)", file=sys.stderr)
        return 1
    with open(sys.argv[2], "wb") as f:
        f.write(frame(table))
    return 0


if __name__ == "__main__":
    sys.exit(main())
