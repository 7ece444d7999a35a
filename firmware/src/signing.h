/* Command signing, the agent's side (SPEC.md s. 12, 1.1 rules): HMAC check, replay state, the persisted mark. */
#ifndef SIGNING_H
#define SIGNING_H

#include <stdbool.h>
#include <stdint.h>

#include "frame.h"
#include "hmac.h"

#define SIGNING_LINK_IDS 16u                 /* per-link_id table; the least recently used is evicted */
#define SIGNING_TICKS_PER_S 100000u          /* timestamp unit: 10 us */
#define SIGNING_WINDOW_TICKS (60u * SIGNING_TICKS_PER_S)  /* too old (new link id) / too new bound */
#define SIGNING_ESTIMATE_STEP_TICKS (10u * SIGNING_TICKS_PER_S)  /* one frame moves the estimate at most this */
#define SIGNING_MARK_AHEAD_TICKS (10u * SIGNING_TICKS_PER_S)  /* persisted mark = accepted + 10 s */

typedef enum {
    SIGN_VALID = 0,
    SIGN_UNSIGNED,
    SIGN_TRUNCATED,
    SIGN_BAD_SIGNATURE,
    SIGN_REPLAYED,
    SIGN_TOO_OLD,
    SIGN_TOO_NEW,
    SIGN_BEFORE_MARK,   /* at or below the mark persisted before this boot */
} sign_result_t;

/* key NULL: no signing, every frame is VALID. Reads the persisted mark through hal_nv_read. */
void signing_init(const uint8_t *key_or_null);
bool signing_enabled(void);
/* Steps 1-2: SIGNED bit / truncated trailer, then the HMAC. */
sign_result_t signing_check_hmac(const frame_t *f);
/* Step 4 (after the ACK memory): replay, too old, too new, the boot mark; accepts (stores) when VALID. */
sign_result_t signing_check_time(const frame_t *f, uint64_t link_now_us);
const char *signing_reason(sign_result_t r);
/* The re-sync (SPEC.md s. 12, "Re-sync"): the nonce a signed PARAM_SET `resync` must carry, new at boot and after
   every re-sync; a refusal for the timestamp names it. */
uint32_t signing_nonce(void);
bool signing_refusal_names_nonce(sign_result_t r);
/* An authenticated re-sync with the current nonce: estimate, link-id table, floor and mark start from its
   timestamp (the mark stored lower, on purpose); a new nonce is drawn. */
void signing_resync(const frame_t *f, uint64_t link_now_us);

#endif
