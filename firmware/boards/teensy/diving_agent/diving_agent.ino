// The diving agent's firmware for the Teensy 3.2 (MK20DX256, 72 MHz, no FPU): the board layer (hal.h) over
// the portable C core in src/core (copied there by `make -C firmware teensy-sketch`).
//
// Wiring (docs/firmware.md): MS5803-01BA and the two M24M02 EEPROMs on I2C (Wire: SDA 18, SCL 19);
// DRV8834 STEP 5, DIR 6, SLEEP 7; ESP8266 on Serial1 (RX1 0, TX1 1) at 115200; USB serial; button on pin 2
// to ground; battery through a 1:1 divider on A9.
#include <Arduino.h>
#include <Wire.h>

extern "C" {
#include "src/core/agent.h"
#include "src/core/hal.h"
}

#if defined(__has_include)
#if __has_include("agent_key.h")
#include "agent_key.h"  // static const uint8_t AGENT_SIGNING_KEY[32] = {...}; not in the repository
#define HAVE_AGENT_KEY 1
#endif
#endif

// ---------------------------------------------------------------- pins and figures
static const uint8_t PIN_STEP = 5;
static const uint8_t PIN_DIR = 6;
static const uint8_t PIN_SLEEP = 7;
static const uint8_t PIN_BUTTON = 2;
static const uint8_t PIN_BATTERY = A9;
static const float BATTERY_DIVIDER = 2.0f;          // 1:1 divider: the pin sees half the cell voltage
static const float ADC_REFERENCE_V = 3.3f;
static const uint32_t LINK_BAUD = 115200;           // the ESP8266 bridge's UART
static const float DEG_PER_STEP = 18.0f / 256.0f;   // 18 deg full step through the 256:1 gear
static const uint32_t STEP_INTERVAL_US = 2000;      // 500 full steps/s
static const float NEUTRAL_DEG = 65.0f;             // the stroke is assumed at mid-travel at power-on
static const uint8_t MS5803_ADDRESS = 0x77;         // CSB low
static const uint8_t EEPROM_BASE_ADDRESS = 0x50;    // M24M02: 1010 E2 A17 A16; chip 1 has E2 high
static const uint32_t EEPROM_CHIP_BYTES = 262144u;
static const uint32_t EEPROM_PAGE_BYTES = 256u;
static const uint8_t WIRE_CHUNK_BYTES = 30;         // Wire's 32-byte buffer minus the two address bytes
static const uint32_t NV_ADDRESS = 0;               // signing mark in the MCU's own 2 KB EEPROM
static const uint32_t TEMPERATURE_EVERY = 40;       // D2 (temperature) once per 40 pressure readings

// ---------------------------------------------------------------- clock
static uint32_t g_last_micros;
static uint64_t g_time_high;

extern "C" uint64_t hal_time_us(void) {
    uint32_t now = micros();
    if (now < g_last_micros) { g_time_high += 1ull << 32; }  // micros() wraps every 71.6 minutes
    g_last_micros = now;
    return g_time_high | now;
}

extern "C" uint64_t hal_link_time_us(void) { return hal_time_us(); }

// ---------------------------------------------------------------- MS5803-01BA (datasheet compensation)
static uint16_t g_prom[8];
static uint32_t g_d2;
static uint32_t g_reads;

static uint32_t ms5803_adc(uint8_t command) {
    Wire.beginTransmission(MS5803_ADDRESS);
    Wire.write(command);
    Wire.endTransmission();
    delayMicroseconds(700);  // OSR 256: 0.6 ms conversion
    Wire.beginTransmission(MS5803_ADDRESS);
    Wire.write((uint8_t)0x00);
    Wire.endTransmission();
    Wire.requestFrom(MS5803_ADDRESS, (uint8_t)3);
    uint32_t v = 0;
    for (int i = 0; i < 3 && Wire.available(); i++) { v = (v << 8) | (uint8_t)Wire.read(); }
    return v;
}

static void ms5803_begin(void) {
    Wire.beginTransmission(MS5803_ADDRESS);
    Wire.write((uint8_t)0x1E);  // reset
    Wire.endTransmission();
    delay(3);
    for (uint8_t i = 0; i < 8; i++) {
        Wire.beginTransmission(MS5803_ADDRESS);
        Wire.write((uint8_t)(0xA0 + 2 * i));
        Wire.endTransmission();
        Wire.requestFrom(MS5803_ADDRESS, (uint8_t)2);
        g_prom[i] = (uint16_t)(((uint16_t)Wire.read() << 8) | (uint8_t)Wire.read());
    }
    g_d2 = ms5803_adc(0x50);
}

extern "C" float hal_pressure_pa(void) {
    if (++g_reads % TEMPERATURE_EVERY == 0) { g_d2 = ms5803_adc(0x50); }
    uint32_t d1 = ms5803_adc(0x40);
    int64_t dt = (int64_t)g_d2 - ((int64_t)g_prom[5] << 8);
    int64_t temp = 2000 + ((dt * g_prom[6]) >> 23);
    int64_t off = ((int64_t)g_prom[2] << 16) + (((int64_t)g_prom[4] * dt) >> 7);
    int64_t sens = ((int64_t)g_prom[1] << 15) + (((int64_t)g_prom[3] * dt) >> 8);
    if (temp < 2000) {  // second-order compensation below 20 C (MS5803-01BA datasheet)
        int64_t t = (temp - 2000) * (temp - 2000);
        off -= 3 * t;
        sens -= (7 * t) >> 3;
    }
    int64_t p = ((((int64_t)d1 * sens) >> 21) - off) >> 15;  // 0.01 mbar = 1 Pa
    return (float)p;
}

// ---------------------------------------------------------------- stepper through the DRV8834
static volatile int32_t g_steps;     // position in full steps from power-on (open loop)
static int32_t g_target_steps;
static uint32_t g_last_step_us;

extern "C" void hal_stepper_set_cmd_deg(float deg) {
    g_target_steps = (int32_t)((deg - NEUTRAL_DEG) / DEG_PER_STEP + (deg >= NEUTRAL_DEG ? 0.5f : -0.5f));
}

extern "C" float hal_stepper_deg(void) { return NEUTRAL_DEG + (float)g_steps * DEG_PER_STEP; }

static void stepper_service(void) {
    if (g_steps == g_target_steps || micros() - g_last_step_us < STEP_INTERVAL_US) { return; }
    bool up = g_target_steps > g_steps;
    digitalWrite(PIN_DIR, up ? HIGH : LOW);
    digitalWrite(PIN_STEP, HIGH);
    delayMicroseconds(2);  // DRV8834: STEP high at least 1.9 us
    digitalWrite(PIN_STEP, LOW);
    g_steps += up ? 1 : -1;
    g_last_step_us = micros();
}

extern "C" float hal_battery_v(void) {
    return (float)analogRead(PIN_BATTERY) * (ADC_REFERENCE_V / 1023.0f) * BATTERY_DIVIDER;
}

// ---------------------------------------------------------------- link: ESP8266 (Serial1) or USB serial
static Stream *g_link = &Serial1;

// The port that last delivered bytes is the link; a switch is a new link (HELLO, sequence tracking restarts).
static void select_link(void) {
    Stream *other = g_link == &Serial1 ? (Stream *)&Serial : (Stream *)&Serial1;
    if (other->available() > 0 && g_link->available() == 0) {
        g_link = other;
        agent_link_up();
    }
}

extern "C" size_t hal_link_read(uint8_t *buf, size_t cap) {
    size_t n = 0;
    while (n < cap && g_link->available() > 0) { buf[n++] = (uint8_t)g_link->read(); }
    return n;
}

extern "C" void hal_link_write(const uint8_t *buf, size_t n) { g_link->write(buf, n); }

// ---------------------------------------------------------------- log: two M24M02 (2 x 256 KiB)
static uint8_t eeprom_device(uint32_t addr) {
    return (uint8_t)(EEPROM_BASE_ADDRESS | ((addr / EEPROM_CHIP_BYTES) << 2) | ((addr >> 16) & 0x3u));
}

// Acknowledge polling: the chip NACKs its address while a write cycle (up to 10 ms) runs. Polled before a
// transaction, not after one, so the last write's cycle overlaps the rest of the loop.
static bool eeprom_ready(uint8_t device) {
    for (uint16_t tries = 0; tries < 2000; tries++) {
        Wire.beginTransmission(device);
        if (Wire.endTransmission() == 0) { return true; }
        delayMicroseconds(10);
    }
    return false;
}

extern "C" uint32_t hal_log_capacity_bytes(void) { return 2u * EEPROM_CHIP_BYTES; }

extern "C" bool hal_log_write(uint32_t addr, const uint8_t *buf, size_t n) {
    while (n > 0) {
        size_t room = EEPROM_PAGE_BYTES - (addr % EEPROM_PAGE_BYTES);  // a page write must not cross a page
        size_t take = n < room ? n : room;
        if (take > WIRE_CHUNK_BYTES) { take = WIRE_CHUNK_BYTES; }
        uint8_t device = eeprom_device(addr);
        if (!eeprom_ready(device)) { return false; }
        Wire.beginTransmission(device);
        Wire.write((uint8_t)(addr >> 8));
        Wire.write((uint8_t)addr);
        Wire.write(buf, take);
        if (Wire.endTransmission() != 0) { return false; }
        addr += take;
        buf += take;
        n -= take;
    }
    return true;
}

extern "C" bool hal_log_read(uint32_t addr, uint8_t *buf, size_t n) {
    while (n > 0) {
        size_t room = EEPROM_CHIP_BYTES - (addr % EEPROM_CHIP_BYTES);  // sequential reads stay in one chip
        size_t take = n < room ? n : room;
        if (take > 32) { take = 32; }
        uint8_t device = eeprom_device(addr);
        if (!eeprom_ready(device)) { return false; }
        Wire.beginTransmission(device);
        Wire.write((uint8_t)(addr >> 8));
        Wire.write((uint8_t)addr);
        if (Wire.endTransmission(false) != 0) { return false; }
        Wire.requestFrom(device, (uint8_t)take);
        for (size_t i = 0; i < take; i++) { buf[i] = (uint8_t)Wire.read(); }
        addr += take;
        buf += take;
        n -= take;
    }
    return true;
}

// ---------------------------------------------------------------- non-volatile area, entropy, simulator hook
extern "C" bool hal_nv_read(uint8_t *buf, size_t n) {
    eeprom_read_block(buf, (const void *)NV_ADDRESS, n);
    return true;
}

extern "C" bool hal_nv_write(const uint8_t *buf, size_t n) {
    eeprom_write_block(buf, (void *)NV_ADDRESS, n);
    return true;
}

extern "C" uint32_t hal_entropy(void) {
    uint32_t x = micros();
    for (int i = 0; i < 32; i++) { x = (x << 1) ^ (x >> 31) ^ (uint32_t)analogRead(A0); }  // ADC noise, floating pin
    return x;
}

extern "C" bool hal_sim_place(float depth_m) {
    (void)depth_m;
    return false;  // hardware: RECOVERING is mandatory
}

// ---------------------------------------------------------------- main loop
static uint32_t g_next_step_us;
static bool g_button_was_down;

static uint32_t chip_id(void) { return *(volatile uint32_t *)0x40048060u; }  // SIM_UIDL

void setup(void) {
    Serial.begin(115200);
    Serial1.begin(LINK_BAUD);
    Wire.begin();
    Wire.setClock(400000);
    pinMode(PIN_STEP, OUTPUT);
    pinMode(PIN_DIR, OUTPUT);
    pinMode(PIN_SLEEP, OUTPUT);
    digitalWrite(PIN_SLEEP, HIGH);
    pinMode(PIN_BUTTON, INPUT_PULLUP);
    ms5803_begin();
#ifdef HAVE_AGENT_KEY
    agent_init(chip_id(), AGENT_SIGNING_KEY);
#else
    agent_init(chip_id(), NULL);
#endif
    g_next_step_us = micros();
}

void loop(void) {
    select_link();
    agent_poll_link();
    stepper_service();
    bool down = digitalRead(PIN_BUTTON) == LOW;
    if (down && !g_button_was_down) { agent_surface(); }  // the button surfaces the agent
    g_button_was_down = down;
    uint32_t now = micros();
    if ((int32_t)(now - g_next_step_us) >= 0) {
        uint32_t period_us = agent_step();
        g_next_step_us += period_us;
        if ((int32_t)(now - g_next_step_us) >= 0) { g_next_step_us = now + period_us; }  // late: no catch-up burst
    }
}
