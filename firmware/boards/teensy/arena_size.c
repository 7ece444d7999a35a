/* Host tool of the Teensy build: the static RAM a learner needs, so each Teensy variant reserves exactly that.
   Usage: arena_size Z_CELLS ZDOT_CELLS ACT_BINS -> "LEARNER_BYTES DUMPS_BYTES" */
#include <stdio.h>
#include <stdlib.h>

#include "learner.h"
#include "proto_params.h"

int main(int argc, char **argv) {
    if (argc != 4) {
        fprintf(stderr, "usage: arena_size Z_CELLS ZDOT_CELLS ACT_BINS\n");
        return 2;
    }
    learner_config_t c;
    learner_default_config(&c);
    c.z_cells = (uint8_t)atoi(argv[1]);
    c.zdot_cells = (uint8_t)atoi(argv[2]);
    c.act_bins = (uint8_t)atoi(argv[3]);
    unsigned states = (unsigned)c.z_cells * c.zdot_cells * c.act_bins + 1u;
    printf("%u %u\n", (unsigned)learner_total_bytes(&c), PARAM_SNAPSHOTS_HELD * PARAM_SNAPSHOT_BYTES_PER_STATE * states);
    return 0;
}
