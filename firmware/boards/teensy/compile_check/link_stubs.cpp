/* COMPILE-CHECK ONLY: empty definitions of the Arduino calls and a reset vector, so the Teensy build links and
   `arm-none-eabi-size` can report the core's and the glue's flash and RAM. Teensyduino's own core (USB stack,
   startup, Wire, Serial) is not in these figures. Nothing here is meant to run. */
#include "Arduino.h"
#include "Wire.h"

extern "C" {
uint32_t micros(void) { return 0; }
void delay(uint32_t) {}
void delayMicroseconds(uint32_t) {}
void pinMode(uint8_t, uint8_t) {}
void digitalWrite(uint8_t, uint8_t) {}
uint8_t digitalRead(uint8_t) { return 1; }
int analogRead(uint8_t) { return 0; }
void eeprom_read_block(void *, const void *, uint32_t) {}
void eeprom_write_block(const void *, void *, uint32_t) {}
}

int Stream::available(void) { return 0; }
int Stream::read(void) { return -1; }
size_t Stream::write(const uint8_t *, size_t n) { return n; }
void usb_serial_class::begin(long) {}
int usb_serial_class::available(void) { return 0; }
int usb_serial_class::read(void) { return -1; }
size_t usb_serial_class::write(const uint8_t *, size_t n) { return n; }
void HardwareSerial::begin(uint32_t) {}
int HardwareSerial::available(void) { return 0; }
int HardwareSerial::read(void) { return -1; }
size_t HardwareSerial::write(const uint8_t *, size_t n) { return n; }
void TwoWire::begin(void) {}
void TwoWire::setClock(uint32_t) {}
void TwoWire::beginTransmission(uint8_t) {}
uint8_t TwoWire::endTransmission(void) { return 0; }
uint8_t TwoWire::endTransmission(uint8_t) { return 0; }
uint8_t TwoWire::requestFrom(uint8_t, uint8_t quantity) { return quantity; }
size_t TwoWire::write(uint8_t) { return 1; }
size_t TwoWire::write(const uint8_t *, size_t n) { return n; }
int TwoWire::available(void) { return 0; }
int TwoWire::read(void) { return 0; }

usb_serial_class Serial;
HardwareSerial Serial1;
TwoWire Wire;

void setup(void);
void loop(void);

extern "C" {
extern uint32_t __data_load, __data_start, __data_end, __bss_start, __bss_end, __stack_top;

void reset_handler(void) {
    uint32_t *src = &__data_load;
    for (uint32_t *dst = &__data_start; dst < &__data_end;) { *dst++ = *src++; }
    for (uint32_t *dst = &__bss_start; dst < &__bss_end;) { *dst++ = 0; }
    setup();
    for (;;) { loop(); }
}

__attribute__((section(".vectors"), used)) void (*const vector_table[2])(void) = {
    (void (*)(void))&__stack_top, reset_handler,
};

void *__dso_handle = 0;
void __cxa_pure_virtual(void) { for (;;) {} }
}
