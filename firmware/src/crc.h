/* CRC-16/CCITT-FALSE (SPEC.md s. 1): poly 0x1021, init 0xFFFF, not reflected, no final XOR. */
#ifndef CRC_H
#define CRC_H

#include <stddef.h>
#include <stdint.h>

#define CRC16_INIT 0xFFFFu

uint16_t crc16_update(uint16_t crc, const uint8_t *p, size_t n);
uint16_t crc16(const uint8_t *p, size_t n);

#endif
