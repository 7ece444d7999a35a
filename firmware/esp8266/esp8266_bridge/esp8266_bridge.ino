// The ESP8266 as a transparent TCP-to-UART bridge for the diving agent: TCP port 23 <-> UART at 115200 baud
// (the Teensy's Serial1). Bytes pass unchanged both ways; the framing is the agent's (COBS + 0x00).
//
// One client at a time. A second client REPLACES the first: the old connection is closed and the new one
// gets the link. A ground station that lost its Wi-Fi link without closing (the usual failure under water)
// must be able to come back at once, and the agent answers the new connection's HELLO (SPEC.md s. 4), so
// the newcomer knows where it stands. This is what the virtual agent does too (simulator/server_transport.py).
//
// Build with the ESP8266 Arduino core (board "Generic ESP8266 Module" or the module you have). Set your
// network in bridge_config.h (not in the repository; see bridge_config.example.h).
#include <ESP8266WiFi.h>

#include "bridge_config.h"  // WIFI_SSID, WIFI_PASSWORD; optional BRIDGE_AP_MODE to be an access point instead

static const uint16_t TCP_PORT = 23;
static const uint32_t UART_BAUD = 115200;
static const size_t CHUNK_BYTES = 256;

WiFiServer server(TCP_PORT);
WiFiClient client;

void setup() {
    Serial.begin(UART_BAUD);  // UART0 (GPIO1 TX, GPIO3 RX) to the Teensy's RX1 / TX1
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
        if (client) { client.stop(); }  // the newcomer replaces the old client
        client = server.available();
        client.setNoDelay(true);
    }
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
