"""CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF, no reflection, no final xor)."""

from __future__ import annotations

import binascii

CRC_INIT = 0xFFFF


def crc16_ccitt_false(data: bytes) -> int:
    """The frame checksum; crc16_ccitt_false(b"123456789") == 0x29B1."""
    return binascii.crc_hqx(data, CRC_INIT)
