/* Signing state: the key, the per-link_id last timestamps (16, LRU), the estimate, the persisted mark. */
#include "signing.h"

#include <string.h>

#include "hal.h"
#include "wire.h"

#define SIGNATURE_BYTES 6u
#define TIMESTAMP_BYTES 6u
#define MARK_MAGIC 0x4B52414Du  /* "MARK": the nv area holds a mark */
#define MARK_RECORD_BYTES 12u

typedef struct {
    uint64_t last_stamp;
    uint32_t used;     /* LRU clock value of its last use */
    uint8_t link_id;
    bool in_use;
} link_entry_t;

static uint8_t g_key[HMAC_KEY_BYTES];
static bool g_enabled;
static link_entry_t g_links[SIGNING_LINK_IDS];
static uint32_t g_lru_clock;
static bool g_have_estimate;
static uint64_t g_best_stamp;
static uint64_t g_best_at_us;
static uint64_t g_boot_mark;    /* refused: timestamps <= this (persisted before boot) */
static uint64_t g_stored_mark;  /* what the nv area holds now */
static uint32_t g_nonce;        /* what the next re-sync must carry */

static void new_nonce(void) {
    g_nonce = hal_entropy();
    if (g_nonce == 0u) { g_nonce = 1u; }  /* 0 is what an unset field reads as */
}

void signing_init(const uint8_t *key_or_null) {
    memset(g_links, 0, sizeof g_links);
    g_lru_clock = 0;
    g_have_estimate = false;
    g_boot_mark = 0;
    g_stored_mark = 0;
    g_enabled = key_or_null != NULL;
    if (!g_enabled) { return; }
    new_nonce();
    memcpy(g_key, key_or_null, HMAC_KEY_BYTES);
    uint8_t record[MARK_RECORD_BYTES];
    if (hal_nv_read(record, sizeof record) && wire_get_u32(record) == MARK_MAGIC) {
        g_boot_mark = wire_get_u64(record + 4);
        g_stored_mark = g_boot_mark;
    }
}

bool signing_enabled(void) { return g_enabled; }

static size_t trailer_at(const frame_t *f) { return (size_t)f->inner_len - PROTO_CRC_BYTES - PROTO_TRAILER_BYTES; }

sign_result_t signing_check_hmac(const frame_t *f) {
    if ((f->flags & FRAME_FLAG_SIGNED) == 0u) { return SIGN_UNSIGNED; }
    if (f->truncated_signature || f->inner_len < PROTO_MIN_INNER + PROTO_TRAILER_BYTES) { return SIGN_TRUNCATED; }
    size_t sig_at = (size_t)f->inner_len - PROTO_CRC_BYTES - SIGNATURE_BYTES;
    uint8_t digest[SHA256_DIGEST_BYTES];
    hmac_sha256(g_key, f->inner, sig_at, digest);
    return hmac_equal(digest, f->inner + sig_at, SIGNATURE_BYTES) ? SIGN_VALID : SIGN_BAD_SIGNATURE;
}

static uint64_t estimate(uint64_t now_us) {
    uint64_t elapsed = now_us > g_best_at_us ? now_us - g_best_at_us : 0u;
    return g_best_stamp + elapsed / (1000000u / SIGNING_TICKS_PER_S);
}

static link_entry_t *find_link(uint8_t link_id) {
    for (unsigned i = 0; i < SIGNING_LINK_IDS; i++) {
        if (g_links[i].in_use && g_links[i].link_id == link_id) { return &g_links[i]; }
    }
    return NULL;
}

static link_entry_t *new_link(uint8_t link_id) {
    link_entry_t *victim = &g_links[0];
    for (unsigned i = 0; i < SIGNING_LINK_IDS; i++) {
        if (!g_links[i].in_use) { victim = &g_links[i]; break; }
        if (g_links[i].used < victim->used) { victim = &g_links[i]; }
    }
    victim->in_use = true;
    victim->link_id = link_id;
    return victim;
}

static void store_mark(uint64_t stamp) {
    uint8_t record[MARK_RECORD_BYTES];
    g_stored_mark = stamp + SIGNING_MARK_AHEAD_TICKS;
    wire_put_u32(record, MARK_MAGIC);
    wire_put_u64(record + 4, g_stored_mark);
    (void)hal_nv_write(record, sizeof record);
}

static void persist_mark(uint64_t stamp) {
    if (stamp > g_stored_mark) { store_mark(stamp); }  /* so at most one write per 10 s of timestamps */
}

static uint64_t trailer_stamp(const frame_t *f) {
    size_t at = trailer_at(f);
    uint64_t stamp = 0;
    for (unsigned i = 0; i < TIMESTAMP_BYTES; i++) { stamp |= (uint64_t)f->inner[at + 1u + i] << (8u * i); }
    return stamp;
}

sign_result_t signing_check_time(const frame_t *f, uint64_t link_now_us) {
    if (!g_enabled) { return SIGN_VALID; }
    uint8_t link_id = f->inner[trailer_at(f)];
    uint64_t stamp = trailer_stamp(f);
    if (stamp <= g_boot_mark) { return SIGN_BEFORE_MARK; }
    link_entry_t *entry = find_link(link_id);
    if (entry != NULL && stamp <= entry->last_stamp) { return SIGN_REPLAYED; }
    if (g_have_estimate) {
        uint64_t now = estimate(link_now_us);
        if (entry == NULL && stamp + SIGNING_WINDOW_TICKS < now) { return SIGN_TOO_OLD; }
        if (stamp > now + SIGNING_WINDOW_TICKS) { return SIGN_TOO_NEW; }
    }
    if (entry == NULL) { entry = new_link(link_id); }
    entry->last_stamp = stamp;
    entry->used = ++g_lru_clock;
    if (!g_have_estimate || stamp > estimate(link_now_us)) {
        /* a bounded step (SPEC s. 12 step 5): a clock ahead cannot ratchet the estimate a minute per frame */
        uint64_t bound = g_have_estimate ? estimate(link_now_us) + SIGNING_ESTIMATE_STEP_TICKS : stamp;
        g_best_stamp = stamp < bound ? stamp : bound;
        g_have_estimate = true;
        g_best_at_us = link_now_us;
    }
    persist_mark(stamp);
    return SIGN_VALID;
}

const char *signing_reason(sign_result_t r) {
    switch (r) {
    case SIGN_VALID: return "";
    case SIGN_UNSIGNED: return "signature unsigned";
    case SIGN_TRUNCATED: return "truncated signature";
    case SIGN_BAD_SIGNATURE: return "signature bad signature";
    case SIGN_REPLAYED: return "signature replayed";
    case SIGN_TOO_OLD: return "signature too old";
    case SIGN_TOO_NEW: return "signature too new";
    case SIGN_BEFORE_MARK: return "signature replayed (before the persisted mark)";
    }
    return "signature refused";
}

uint32_t signing_nonce(void) { return g_nonce; }

bool signing_refusal_names_nonce(sign_result_t r) {
    return r == SIGN_REPLAYED || r == SIGN_TOO_OLD || r == SIGN_TOO_NEW || r == SIGN_BEFORE_MARK;
}

void signing_resync(const frame_t *f, uint64_t link_now_us) {
    uint64_t stamp = trailer_stamp(f);
    memset(g_links, 0, sizeof g_links);
    link_entry_t *entry = new_link(f->inner[trailer_at(f)]);
    entry->last_stamp = stamp;
    entry->used = ++g_lru_clock;
    g_have_estimate = true;
    g_best_stamp = stamp;
    g_best_at_us = link_now_us;
    g_boot_mark = stamp;  /* the floor: nothing at or before the re-sync's own time */
    store_mark(stamp);    /* lower than the stored mark: a reboot must not bring the lock-out back */
    new_nonce();
}
