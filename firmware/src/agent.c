/* Boot order and the loop's two calls; a board's main loop:
   for (;;) { agent_poll_link(); wait until the next step time; period = agent_step(); } */
#include "agent.h"

#include "commands.h"
#include "dumps.h"
#include "link.h"
#include "logring.h"
#include "modes.h"
#include "params.h"

static void pump_replies(void) { (void)commands_pump(COMMANDS_REPLIES_PER_POLL); }

/* The link's calls upward: commands go to their handlers, a HEARTBEAT reads the mode machine. */
static const link_upcalls_t k_link_upcalls = {
    .command = commands_handle,
    .pump_replies = pump_replies,
    .mode = modes_mode,
    .episode = modes_episode,
    .generation = modes_generation,
};

void agent_init(uint32_t node_id, const uint8_t *key_or_null) {
    params_init();
    dumps_init();
    logring_init();
    commands_init();
    modes_init(commands_episode_dumps);
    link_init(node_id, key_or_null, &k_link_upcalls);
}

void agent_poll_link(void) { link_poll(); }

uint32_t agent_step(void) {
    uint32_t period_us = modes_step();
    link_tick();
    return period_us;
}

void agent_link_up(void) { link_reset(); }

void agent_surface(void) {
    verdict_t v;
    modes_cmd_surface(true, &v);
}
