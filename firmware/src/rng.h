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
/* uniform(state) < p, decided on the 53-bit draw as Python does (p in [0, 1]) */
int      rng_below(rng_t *r, float p);

#endif
