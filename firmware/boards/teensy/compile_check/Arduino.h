/* COMPILE-CHECK ONLY: the few Teensyduino declarations the sketch uses, so `make -C firmware teensy` can compile
   and link the board glue without Teensyduino installed. The real build uses Teensyduino's Arduino.h
   (platformio or the Arduino IDE); nothing here runs on a board. */
#ifndef COMPILE_CHECK_ARDUINO_H
#define COMPILE_CHECK_ARDUINO_H

#include <stddef.h>
#include <stdint.h>

#define HIGH 1
#define LOW 0
#define INPUT 0
#define OUTPUT 1
#define INPUT_PULLUP 2
#define A0 14
#define A9 23

extern "C" {
uint32_t micros(void);
void delay(uint32_t ms);
void delayMicroseconds(uint32_t us);
void pinMode(uint8_t pin, uint8_t mode);
void digitalWrite(uint8_t pin, uint8_t value);
uint8_t digitalRead(uint8_t pin);
int analogRead(uint8_t pin);
void eeprom_read_block(void *buf, const void *addr, uint32_t n);
void eeprom_write_block(const void *buf, void *addr, uint32_t n);
}

class Stream {
public:
    virtual int available(void);
    virtual int read(void);
    virtual size_t write(const uint8_t *buf, size_t n);
};

class usb_serial_class : public Stream {
public:
    void begin(long baud);
    int available(void) override;
    int read(void) override;
    size_t write(const uint8_t *buf, size_t n) override;
};

class HardwareSerial : public Stream {
public:
    void begin(uint32_t baud);
    int available(void) override;
    int read(void) override;
    size_t write(const uint8_t *buf, size_t n) override;
};

extern usb_serial_class Serial;
extern HardwareSerial Serial1;

#endif
