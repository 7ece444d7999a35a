/* COMPILE-CHECK ONLY: the TwoWire calls the sketch uses (Teensyduino's Wire.h in a real build). */
#ifndef COMPILE_CHECK_WIRE_H
#define COMPILE_CHECK_WIRE_H

#include <stddef.h>
#include <stdint.h>

class TwoWire {
public:
    void begin(void);
    void setClock(uint32_t hz);
    void beginTransmission(uint8_t address);
    uint8_t endTransmission(void);
    uint8_t endTransmission(uint8_t send_stop);
    uint8_t requestFrom(uint8_t address, uint8_t quantity);
    size_t write(uint8_t data);
    size_t write(const uint8_t *data, size_t n);
    int available(void);
    int read(void);
};

extern TwoWire Wire;

#endif
