// What the ESP8266 core's host emulation (tests/host/common/MockWiFiServer*.cpp, which replaces the core's
// libraries/ESP8266WiFi/src/WiFiServer.cpp) lacks of the calls the bridge sketch makes. Linked into the emulation's
// core by tests/firmware/test_esp8266_bridge.py; each body is the real core's, so the sketch is compiled unchanged.
#include <ESP8266WiFi.h>

// The real core's WiFiServer.cpp: remembers the choice and hands it to each accepted client. The emulation's
// accept() does not hand it on, and its sockets ignore no-delay (ClientContext::setNoDelay is a "TODO" there), so
// on the host this only keeps the link whole; the sketch also sets it on each client itself.
void WiFiServer::setNoDelay(bool nodelay) { _noDelay = nodelay ? _ndTrue : _ndFalse; }
