/* The agent's link layer: frames out (with the on-board log), frames in, HELLO / HEARTBEAT / TIMESYNC,
   commands with exactly one ACK each and the 16-entry ACK memory, signing checks. */
#ifndef LINK_H
#define LINK_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "frame.h"
#include "params.h"

#define LINK_ACK_MEMORY 16u          /* the last 16 (msg_id, seq, result) answered */
#define LINK_HELLO_REPEAT_US 1000000u  /* HELLO once per second of link time until the ground is heard */
#define LINK_HEARTBEAT_US 1000000u   /* HEARTBEAT once per second of agent time */

/* What the link calls upward: it sits below the command handlers and the mode machine, and agent.c wires
   them in, so that this header names nothing above it. */
typedef struct {
    /* The verdict for a command frame; with apply set (after its ACK went out) it is also carried out. */
    void (*command)(const frame_t *f, bool apply, verdict_t *v);
    /* Sends the reply frames one poll may send (after the frames read in that poll were handled). */
    void (*pump_replies)(void);
    /* The mode, the episode and the learner generation a HEARTBEAT (and HELLO) reports. */
    uint8_t (*mode)(void);
    uint32_t (*episode)(void);
    uint32_t (*generation)(void);
} link_upcalls_t;

/* up: in static storage (the link keeps the pointer). */
void link_init(uint32_t node_id, const uint8_t *key_or_null, const link_upcalls_t *up);
/* A new link (TCP connection, port opened): sequence tracking restarts, HELLO goes out. */
void link_reset(void);
/* Reads the bytes the board has and handles every frame in them; pending replies; the HELLO repeat. */
void link_poll(void);
/* After each control step: HEARTBEAT when due. */
void link_tick(void);

/* Outbound (the mode machine and the command handlers use these). */
void link_send(uint8_t msg_id, const uint8_t *payload, size_t n, uint8_t flags);
/* A SAMPLE / EPISODE frame: into the on-board log, then onto the link. */
void link_send_logged(uint8_t msg_id, const uint8_t *payload, size_t n, uint32_t sample, bool is_sample);
/* An inner frame from the log, re-sent with its msg_id and payload, REPLAYED set and a new seq. */
void link_send_replayed(const uint8_t *inner, size_t len);
void link_text(uint8_t severity, const char *line);

/* Link time of the last valid frame from the ground (0 before any). */
uint64_t link_last_ground_rx_us(void);
const frame_stats_t *link_stats(void);
uint32_t link_signing_rejects(void);
uint16_t link_next_seq(void);

#endif
