/* Host tool of the Teensy build: the static RAM a learner needs, so each Teensy variant reserves exactly that.
   Usage: arena_size Z_CELLS ZDOT_CELLS ACT_BINS [SHARED] -> "LEARNER_BYTES DUMPS_BYTES"
   SHARED 1: the shared-model learner (in-place sweeps, as its presets, and room for planning's early stop and for
   planning on growth),
   whose snapshot copies are at most VALUES (4 S bytes; its Q_VALUES is rendered live, SPEC.md s. 13). */
#include <stdio.h>
#include <stdlib.h>

#include "learner.h"
#include "proto_params.h"

int main(int argc, char **argv) {
    if (argc != 4 && argc != 5) {
        fprintf(stderr, "usage: arena_size Z_CELLS ZDOT_CELLS ACT_BINS [SHARED]\n");
        return 2;
    }
    learner_config_t c;
    learner_default_config(&c);
    c.z_cells = (uint8_t)atoi(argv[1]);
    c.zdot_cells = (uint8_t)atoi(argv[2]);
    c.act_bins = (uint8_t)atoi(argv[3]);
    c.shared_model = argc == 5 && atoi(argv[4]) != 0;
    c.in_place_sweeps = c.shared_model;
    /* Room for planning's early stop too (its last greedy action per state, 1 bit each; any k > 0 needs the same),
       so that PARAM_SET plan_stable_sweeps is not refused for want of storage. */
    c.plan_stable_sweeps = c.shared_model ? 1u : 0u;
    /* And for planning on growth (a uint16 count per type since the last plan; any growth > 0 needs the same). */
    c.plan_growth = c.shared_model ? 1.0f : 0.0f;
    unsigned states = (unsigned)c.z_cells * c.zdot_cells * c.act_bins + 1u;
    unsigned per_state = c.shared_model ? PARAM_SHARED_SNAPSHOT_BYTES_PER_STATE : PARAM_SNAPSHOT_BYTES_PER_STATE;
    printf("%u %u\n", (unsigned)learner_total_bytes(&c), PARAM_SNAPSHOTS_HELD * per_state * states);
    return 0;
}
