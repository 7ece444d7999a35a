// The ESP8266 as a transparent TCP-to-UART bridge for the diving agent: TCP port 23 <-> UART at 115200 baud
// (the Teensy's Serial1). Bytes pass unchanged both ways; the framing is the agent's (COBS + 0x00).
//
// One client at a time. A second client REPLACES the first: a ground station that lost its Wi-Fi link without
// closing (the usual failure under water) must be able to come back at once, and the agent answers the new
// connection's HELLO (SPEC.md s. 4), so the newcomer knows where it stands. The old client is told first
// (SPEC.md s. 4, "A link taken by another ground"): the TEXT `link taken by another ground`, so that a ground
// still there stops instead of reconnecting and taking the link back. The bridge builds no frame: it writes the
// bytes `python -m protocol.gen_c` generates (firmware/generated/link_taken_frame.h). Then the old client waits in
// a closing slot, its bytes read and dropped, until it closes or CLOSING_LINGER_MS pass, and only then is it
// stopped: a close with unread bytes is a reset, and a reset would discard the TEXT unread. This is what the
// virtual agent does too (simulator/serve/transport.py, tell_replaced).
//
// Build with the ESP8266 Arduino core 3.x, as its users do (docs/firmware.md walks through it). Set your network in
// bridge_config.h (not in the repository; see bridge_config.example.h). The generated header is outside the sketch
// folder, so the build is told where it is:
//   pio run -d firmware/esp8266 -t upload      (firmware/esp8266/platformio.ini: ESP-01 1 MB, or -e esp12e)
//   arduino-cli compile --fqbn esp8266:esp8266:generic --build-property "compiler.cpp.extra_flags=-I$PWD/firmware/generated" firmware/esp8266/esp8266_bridge
// (arduino-cli from the repository's top; or copy firmware/generated/link_taken_frame.h beside this file, and again
// after protocol/ changes). Not built for the ESP8266 itself here (no Xtensa toolchain): CI compiles this file with
// warnings as errors against the same core's host emulation and runs it between `dive` and the agents
// (tests/firmware/test_esp8266_bridge.py).
#include <ESP8266WiFi.h>

#include "bridge_config.h"  // WIFI_SSID, WIFI_PASSWORD; optional BRIDGE_AP_MODE to be an access point instead
#include "link_taken_frame.h"  // LINK_TAKEN_FRAME, LINK_TAKEN_FRAME_BYTES: 0x00, then the TEXT frame

static const uint16_t TCP_PORT = 23;
static const uint32_t UART_BAUD = 115200;
static const size_t CHUNK_BYTES = 256;
// The UART's receive buffer (the core's default is 256 B, 22 ms of 115200 baud): a client.write() waits while Wi-Fi
// is slow to take bytes, and the agent's bursts (a reply stream, 16 frames per poll) must wait in RAM meanwhile, not
// overflow. 4 KB is 0.36 s of the UART; the ESP8266 has RAM to spare (the core's WiFiTelnetToSerial uses 1 KB).
static const size_t UART_RX_BYTES = 4096;
static const uint32_t CLOSING_LINGER_MS = 2000;  // a replaced client is stopped when it closes, or after this

WiFiServer server(TCP_PORT);
WiFiClient client;
WiFiClient closing;  // the replaced client, told and waited for
static bool closing_held = false;
static uint32_t closing_since_ms = 0;

static void drop_input(WiFiClient &c) {
    while (c.available()) { (void)c.read(); }  // not for the agent any more
}

static void tell_replaced(WiFiClient &old) {
    if (closing_held) { closing.stop(); }  // a third client within the linger: the second's time is up
    drop_input(old);
    old.write(LINK_TAKEN_FRAME, LINK_TAKEN_FRAME_BYTES);
    closing = old;
    closing_held = true;
    closing_since_ms = millis();
}

static void service_closing() {
    if (!closing_held) { return; }
    drop_input(closing);  // a command it sent as the newcomer connected: read, so the stop is no reset
    if (!closing.connected() || (uint32_t)(millis() - closing_since_ms) >= CLOSING_LINGER_MS) {
        closing.stop();
        closing_held = false;
    }
}

void setup() {
    Serial.begin(UART_BAUD);  // UART0 (GPIO1 TX, GPIO3 RX) to the Teensy's RX1 / TX1
    Serial.setRxBufferSize(UART_RX_BYTES);
#ifdef BRIDGE_AP_MODE
    WiFi.mode(WIFI_AP);
    WiFi.softAP(WIFI_SSID, WIFI_PASSWORD);
#else
    WiFi.mode(WIFI_STA);
    WiFi.begin(WIFI_SSID, WIFI_PASSWORD);
    while (WiFi.status() != WL_CONNECTED) { delay(100); }
#endif
    server.begin();
    server.setNoDelay(true);  // a frame goes out now, not after Nagle's wait
}

void loop() {
    if (server.hasClient()) {
        WiFiClient newcomer = server.accept();
        if (client.connected()) { tell_replaced(client); } else { client.stop(); }  // the newcomer replaces it
        client = newcomer;
        client.setNoDelay(true);
    }
    service_closing();
    uint8_t buf[CHUNK_BYTES];
    if (client && client.connected()) {
        size_t n = 0;
        while (client.available() && n < sizeof buf) { buf[n++] = (uint8_t)client.read(); }
        if (n) { Serial.write(buf, n); }
    }
    size_t m = 0;
    while (Serial.available() && m < sizeof buf) { buf[m++] = (uint8_t)Serial.read(); }
    if (m && client && client.connected()) { client.write(buf, m); }  // no client: the agent's bytes are dropped
    yield();
}
