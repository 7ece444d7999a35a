/* SplitMix64 (Steele, Lea, Flood 2014), bit for bit the stream of learning/rng.py. */
#include "rng.h"

#define GOLDEN_GAMMA 0x9E3779B97F4A7C15ull
#define MIX_1 0xBF58476D1CE4E5B9ull
#define MIX_2 0x94D049BB133111EBull
#define TWO_POW_53_F 9007199254740992.0f

void rng_seed(rng_t *r, uint64_t state)
{
    r->state = state;
}

uint64_t rng_next_u64(rng_t *r)
{
    r->state += GOLDEN_GAMMA;
    uint64_t z = r->state;
    z = (z ^ (z >> 30)) * MIX_1;
    z = (z ^ (z >> 27)) * MIX_2;
    return z ^ (z >> 31);
}

int rng_coin(rng_t *r)
{
    /* uniform = (x >> 11) / 2^53 < 0.5 exactly when the top bit is clear */
    return (rng_next_u64(r) >> 63) == 0u;
}

uint64_t rng_draw53(rng_t *r)
{
    return rng_next_u64(r) >> 11;
}

uint64_t rng_scale53(float p)
{
    /* A power-of-two scale is exact in float, and the product is an integer below 2^64. */
    if (p <= 0.0f) {
        return 0u;
    }
    return (uint64_t)(p * TWO_POW_53_F);
}
