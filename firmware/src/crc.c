/* CRC-16/CCITT-FALSE, nibble table: 32 bytes of flash, half the shifts of the bitwise loop. */
#include "crc.h"

static const uint16_t CRC_NIBBLE[16] = {
    0x0000u, 0x1021u, 0x2042u, 0x3063u, 0x4084u, 0x50A5u, 0x60C6u, 0x70E7u,
    0x8108u, 0x9129u, 0xA14Au, 0xB16Bu, 0xC18Cu, 0xD1ADu, 0xE1CEu, 0xF1EFu,
};

uint16_t crc16_update(uint16_t crc, const uint8_t *p, size_t n) {
    while (n--) {
        crc ^= (uint16_t)((uint16_t)*p++ << 8);
        crc = (uint16_t)((crc << 4) ^ CRC_NIBBLE[crc >> 12]);
        crc = (uint16_t)((crc << 4) ^ CRC_NIBBLE[crc >> 12]);
    }
    return crc;
}

uint16_t crc16(const uint8_t *p, size_t n) { return crc16_update(CRC16_INIT, p, n); }
