// The network settings the bridge sketch expects (bridge_config.example.h), for its build against the ESP8266 core's
// host emulation (tests/firmware/test_esp8266_bridge.py). The emulation reports Wi-Fi as already associated, so the
// station loop in setup() passes at once and these values reach no radio.
#define WIFI_SSID "test-network"
#define WIFI_PASSWORD "test-password"
