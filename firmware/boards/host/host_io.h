/* The host board's I/O block: Python (simulator/firmware_host.py) fills the inputs before each call and
   drains the outputs after it, so no Python callback runs inside the control loop. */
#ifndef HOST_IO_H
#define HOST_IO_H

#include <stdint.h>

#define HOST_RX_BYTES 4096u
#define HOST_TX_BYTES 262144u   /* a LOG_REQUEST replay or a COUNTS dump between two drains */
#define HOST_NV_BYTES 64u
#define HOST_LOG_MAX_BYTES (512u * 1024u)  /* 2 x M24M02 */
#define HOST_IO_VERSION 1u

typedef struct {
    uint32_t version;          /* HOST_IO_VERSION: the Python side checks it and the size */
    uint32_t size_bytes;       /* sizeof(host_io_t) */
    /* inputs */
    uint64_t time_us;          /* agent clock */
    uint64_t link_time_us;     /* the link's real (wall) clock */
    float pressure_pa;         /* the sensor reading the next hal_pressure_pa returns */
    float stepper_deg;         /* motor-side angle now (counted steps; the output is the plant's) */
    float battery_v;
    uint32_t rx_len;           /* bytes in rx not yet read by the core */
    uint32_t rx_pos;
    /* outputs */
    float stepper_cmd_deg;     /* commanded gear angle */
    uint32_t tx_len;           /* bytes in tx for Python to send */
    uint32_t tx_dropped;       /* bytes that did not fit (Python drains after every call) */
    uint32_t pressure_reads;   /* hal_pressure_pa calls (the Python sensor draws one reading per call) */
    uint32_t nv_writes;
    uint32_t log_capacity_bytes;  /* set before host_init; at most HOST_LOG_MAX_BYTES */
    uint32_t entropy_state;
    uint32_t nv_len;
    uint8_t nv[HOST_NV_BYTES];  /* the signing mark's non-volatile area (Python persists it to a file) */
    uint8_t rx[HOST_RX_BYTES];
    uint8_t tx[HOST_TX_BYTES];
} host_io_t;

host_io_t *host_io(void);
uint32_t host_io_size(void);
void host_init(uint32_t node_id, const uint8_t *key_or_null);
void host_poll(void);
uint32_t host_step(void);
void host_link_up(void);
uint16_t host_next_seq(void);
#define HOST_COUNTERS 5u
/* next_sample, signing_rejects, rx_lost, rx_rejects, rx_frames (serve --report, tests) */
void host_counters(uint32_t out[HOST_COUNTERS]);

#endif
