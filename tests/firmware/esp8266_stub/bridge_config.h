// The network settings the sketch expects (bridge_config.example.h), for the host syntax check.
#define WIFI_SSID "test-network"
#define WIFI_PASSWORD "test-password"
