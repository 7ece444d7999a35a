/* Dump snapshots (SPEC.md s. 10, 1.1): the newest 4 of any kind; COUNTS rendered live and STALE on change. */
#ifndef DUMPS_H
#define DUMPS_H

#include <stdbool.h>
#include <stdint.h>

#include "proto_params.h"

#define DUMPS_CHUNK_BYTES 224u   /* a sender puts at most 224 data bytes in a DUMP_CHUNK */
#ifndef DUMPS_ARENA_BYTES
#define DUMPS_ARENA_BYTES (PARAM_SNAPSHOTS_HELD * PARAM_SNAPSHOT_BYTES_PER_STATE * 128u)  /* S <= 128 */
#endif

/* Largest S whose copied snapshots fit the arena (the RAM budget check uses it too); a shared-model learner
   copies at most VALUES (its Q_VALUES is rendered live). */
uint32_t dumps_max_states(bool shared_model);
void dumps_init(void);
/* The model changed (a transition observed, a reset) or, for a shared model, its values (a planning slice):
   the snapshots rendered live (COUNTS; Q_VALUES of a shared model) go stale. */
void dumps_model_changed(void);
/* Takes a snapshot of kind (1-4) from the learner; returns its id (never 0). */
uint32_t dumps_take(uint8_t kind);
/* The snapshot held under id with that kind: its size and episode; false if not held (STALE). */
bool dumps_find(uint32_t dump_id, uint8_t kind, uint32_t *total_bytes, uint32_t *episode);
/* True if the snapshot under dump_id is rendered when read (COUNTS, a shared model's Q_VALUES). */
bool dumps_live(uint32_t dump_id);
/* Copies [offset, offset + n) of a held snapshot into out. */
void dumps_read(uint32_t dump_id, uint32_t offset, uint8_t *out, uint32_t n);

#endif
