/* The on-board log (SPEC.md s. 7, 1.1): records of u8 length + inner frame in the EEPROM, oldest overwritten. */
#ifndef LOGRING_H
#define LOGRING_H

#include <stdbool.h>
#include <stdint.h>

#include "proto_messages.h"

#define LOGRING_REPLAY_MAX_SAMPLES 512u  /* one LOG_REQUEST replays at most this many SAMPLEs (issue 13) */

typedef struct {
    uint32_t first_sample;  /* oldest SAMPLE index held (== next_sample when empty) */
    uint32_t next_sample;   /* index the next SAMPLE gets */
    uint32_t bytes_used;    /* sum of (1 + L) over the records held */
    uint32_t capacity_bytes;
} logring_info_t;

/* An empty log over hal_log_* (contents from before a reboot are not kept: samples restart at 0). */
void logring_init(void);
/* Stores one SAMPLE / EPISODE_START / EPISODE_END inner frame whose sample index is `sample`. */
void logring_append(const uint8_t *inner, uint8_t len, uint32_t sample, bool is_sample);
void logring_info(logring_info_t *out);

/* A replay cursor over [first, end): records in production order. */
typedef struct {
    uint32_t addr;          /* address of the next record to look at */
    uint32_t seq_at_start;  /* the ring's drop count when the cursor was made: a wrap invalidates it */
    uint32_t end_sample;
    uint32_t replayed;      /* frames re-sent so far */
    uint32_t samples;       /* SAMPLE frames among them */
    bool active;
} logring_cursor_t;

void logring_cursor_start(logring_cursor_t *c, uint32_t first_sample, uint32_t end_sample);
/* The next record to replay into inner (room for PROTO_MAX_INNER); false when the replay is finished. */
bool logring_cursor_next(logring_cursor_t *c, uint8_t *inner, uint8_t *len);

#endif
