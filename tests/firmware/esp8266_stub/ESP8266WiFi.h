// A minimal stub of the ESP8266 core's WiFi API the bridge sketch uses (see Arduino.h here): declarations only.
#pragma once
#include "Arduino.h"

enum WiFiMode_t { WIFI_OFF = 0, WIFI_STA = 1, WIFI_AP = 2, WIFI_AP_STA = 3 };
enum wl_status_t { WL_IDLE_STATUS = 0, WL_CONNECTED = 3, WL_DISCONNECTED = 6 };

class ESP8266WiFiClass {
public:
    bool mode(WiFiMode_t mode);
    bool softAP(const char *ssid, const char *passphrase);
    wl_status_t begin(const char *ssid, const char *passphrase);
    wl_status_t status();
};

extern ESP8266WiFiClass WiFi;

class WiFiClient {
public:
    int available();
    int read();
    size_t write(const uint8_t *buffer, size_t size);
    uint8_t connected();
    bool stop(unsigned int max_wait_ms = 0);
    void setNoDelay(bool no_delay);
    explicit operator bool();
};

class WiFiServer {
public:
    explicit WiFiServer(uint16_t port);
    void begin();
    void setNoDelay(bool no_delay);
    bool hasClient();
    WiFiClient available(uint8_t *status = nullptr);
};
