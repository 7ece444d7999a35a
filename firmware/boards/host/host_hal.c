/* hal.h for the host: every call reads or writes the I/O block Python shares through ctypes. */
#include <string.h>

#include "agent.h"
#include "hal.h"
#include "host_io.h"
#include "link.h"
#include "modes.h"

static host_io_t g_io = {HOST_IO_VERSION, sizeof(host_io_t), 0, 0, 101325.0f, 65.0f, 4.2f, 0, 0, 65.0f, 0, 0, 0, 0,
                         HOST_LOG_MAX_BYTES, 0x9E3779B9u, 0, {0}, {0}, {0}};
static uint8_t g_log[HOST_LOG_MAX_BYTES];

host_io_t *host_io(void) { return &g_io; }
uint32_t host_io_size(void) { return (uint32_t)sizeof(host_io_t); }

uint64_t hal_time_us(void) { return g_io.time_us; }
uint64_t hal_link_time_us(void) { return g_io.link_time_us; }

float hal_pressure_pa(void) {
    g_io.pressure_reads++;
    return g_io.pressure_pa;
}

void hal_stepper_set_cmd_deg(float deg) { g_io.stepper_cmd_deg = deg; }
float hal_stepper_deg(void) { return g_io.stepper_deg; }
float hal_battery_v(void) { return g_io.battery_v; }

size_t hal_link_read(uint8_t *buf, size_t cap) {
    size_t n = g_io.rx_len - g_io.rx_pos;
    if (n > cap) { n = cap; }
    memcpy(buf, g_io.rx + g_io.rx_pos, n);
    g_io.rx_pos += (uint32_t)n;
    if (g_io.rx_pos == g_io.rx_len) { g_io.rx_pos = g_io.rx_len = 0; }
    return n;
}

void hal_link_write(const uint8_t *buf, size_t n) {
    if (g_io.tx_len + n > HOST_TX_BYTES) {  /* like a full UART FIFO: the frame is lost, counted */
        g_io.tx_dropped += (uint32_t)n;
        return;
    }
    memcpy(g_io.tx + g_io.tx_len, buf, n);
    g_io.tx_len += (uint32_t)n;
}

uint32_t hal_log_capacity_bytes(void) {
    return g_io.log_capacity_bytes < HOST_LOG_MAX_BYTES ? g_io.log_capacity_bytes : HOST_LOG_MAX_BYTES;
}

bool hal_log_read(uint32_t addr, uint8_t *buf, size_t n) {
    if ((uint64_t)addr + n > hal_log_capacity_bytes()) { return false; }
    memcpy(buf, g_log + addr, n);
    return true;
}

bool hal_log_write(uint32_t addr, const uint8_t *buf, size_t n) {
    if ((uint64_t)addr + n > hal_log_capacity_bytes()) { return false; }
    memcpy(g_log + addr, buf, n);
    return true;
}

bool hal_nv_read(uint8_t *buf, size_t n) {
    if (n > g_io.nv_len) { return false; }
    memcpy(buf, g_io.nv, n);
    return true;
}

bool hal_nv_write(const uint8_t *buf, size_t n) {
    if (n > HOST_NV_BYTES) { return false; }
    memcpy(g_io.nv, buf, n);
    g_io.nv_len = (uint32_t)n;
    g_io.nv_writes++;
    return true;
}

uint32_t hal_entropy(void) {  /* xorshift32 from the seed Python puts in entropy_state */
    uint32_t x = g_io.entropy_state ? g_io.entropy_state : 0x9E3779B9u;
    x ^= x << 13;
    x ^= x >> 17;
    x ^= x << 5;
    g_io.entropy_state = x;
    return x;
}

bool hal_sim_place(float depth_m) {
    (void)depth_m;
    return false;  /* RECOVERING is mandatory: the firmware never teleports its plant */
}

void host_init(uint32_t node_id, const uint8_t *key_or_null) { agent_init(node_id, key_or_null); }
void host_poll(void) { agent_poll_link(); }
uint32_t host_step(void) { return agent_step(); }
void host_link_up(void) { agent_link_up(); }

uint16_t host_next_seq(void) { return link_next_seq(); }

void host_counters(uint32_t out[HOST_COUNTERS]) {
    const frame_stats_t *s = link_stats();
    out[0] = modes_next_sample();
    out[1] = link_signing_rejects();
    out[2] = s->lost;
    out[3] = frame_rejects(s);
    out[4] = s->frames;
}
