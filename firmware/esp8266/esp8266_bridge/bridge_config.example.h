// Copy to bridge_config.h (kept out of the repository) and fill in your network.
#define WIFI_SSID "your-network"
#define WIFI_PASSWORD "your-password"
// #define BRIDGE_AP_MODE 1  // uncomment: the ESP8266 opens its own network with this name and password
