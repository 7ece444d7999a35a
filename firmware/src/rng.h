/* SplitMix64, the random stream learning/rng.py uses, so C and Python draw the same numbers. */
#ifndef RNG_H
#define RNG_H

#include <stdint.h>

typedef struct {
    uint64_t state;
} rng_t;

void     rng_seed(rng_t *r, uint64_t state);
uint64_t rng_next_u64(rng_t *r);
/* true with probability 1/2: the same draw as Python's uniform(state) < 0.5 */
int      rng_coin(rng_t *r);
/* The 53-bit draw behind Python's uniform(state) = draw / 2^53. */
uint64_t rng_draw53(rng_t *r);
/* p * 2^53, exact for p in [0, 1]: draw < rng_scale53(p) is exactly uniform < p. */
uint64_t rng_scale53(float p);

#endif
