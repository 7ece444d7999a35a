/* Parameters (SPEC.md s. 9, 1.1): the generated table, f32 storage, lookup, refusal rules, PARAM_VALUE. */
#ifndef PARAMS_H
#define PARAMS_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "learner.h"
#include "proto_messages.h"
#include "proto_params.h"

#define PARAMS_REASON_BYTES 96u

typedef struct {
    uint8_t result;                    /* AckResult */
    char reason[PARAMS_REASON_BYTES];  /* "" when accepted */
} verdict_t;

void  params_init(void);
float params_get(param_index_t i);
/* Index by PARAM_GET/PARAM_SET rules: -1 = by name (24 bytes, NUL-padded), 0..count-1 = by index. */
bool  params_lookup(int16_t index, const char name[PARAM_NAME_BYTES], uint16_t *out, verdict_t *v);
/* Whether value (binary64 bits) may be stored in mode: BAD_VALUE checks first, then the mode;
   stores it when apply is set and it is accepted. */
void  params_set(uint16_t index, uint64_t value_bits, uint8_t mode, bool apply, verdict_t *v);
/* The PARAM_VALUE payload of one parameter; returns its length. */
size_t params_value_payload(uint16_t index, uint8_t *out);
/* The learner configuration the current values describe. */
void  params_learner_config(learner_config_t *c);
/* Bytes a learner configuration needs against the RAM budget (model + snapshot copies). */
uint32_t params_ram_bytes(const learner_config_t *c);

void verdict_ok(verdict_t *v);
void verdict_set(verdict_t *v, uint8_t result, const char *reason);

#endif
