/* Command handlers (SPEC.md s. 5, 1.1 matrix) and the replies that follow an ACK, streamed a few per poll. */
#ifndef COMMANDS_H
#define COMMANDS_H

#include <stdbool.h>
#include <stdint.h>

#include "frame.h"
#include "params.h"

#define COMMANDS_REPLIES_PER_POLL 16u  /* reply frames sent per poll, so replies interleave with the loop */
/* A chunk of a shared model's live Q_VALUES computes 56 Q values, the work of 28 planning backups (100 backups
   took at most 325 033 instructions in QEMU, docs/firmware.md): it counts as this many replies, so a poll sends
   2 of them. */
#define COMMANDS_LIVE_Q_CHUNK_COST 8u

void commands_init(void);
/* The verdict for a command frame; with apply set (after the ACK went out) it is also carried out. */
void commands_handle(const frame_t *f, bool apply, verdict_t *v);
/* VALUES then POLICY snapshots, unprompted after an episode (dump_each_episode). */
void commands_episode_dumps(void);
/* Sends up to COMMANDS_REPLIES_PER_POLL pending reply frames; false when none are left. */
bool commands_pump(uint32_t budget);

#endif
