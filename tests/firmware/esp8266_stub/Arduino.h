// A minimal stub of the Arduino API the ESP8266 bridge sketch uses: declarations only, for a host syntax and type
// check (tests/firmware/test_esp8266_bridge.py). Signatures as in the ESP8266 Arduino core; nothing here runs.
#pragma once
#include <stddef.h>
#include <stdint.h>

void delay(unsigned long ms);
unsigned long millis();
void yield();

class HardwareSerial {
public:
    void begin(unsigned long baud);
    int available();
    int read();
    size_t write(const uint8_t *buffer, size_t size);
};

extern HardwareSerial Serial;
