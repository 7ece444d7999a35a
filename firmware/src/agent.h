/* The on-board program's entry points: a board calls these and nothing else of the core. */
#ifndef AGENT_H
#define AGENT_H

#include <stdint.h>

/* Boots the program: parameters at their defaults, learner configured, log empty, HELLO sent.
   key_or_null: the 32-byte signing key (commands must then be signed), or NULL. */
void     agent_init(uint32_t node_id, const uint8_t *key_or_null);
/* Reads the link's bytes and handles the frames in them; sends pending replies. */
void     agent_poll_link(void);
/* One control step of the current mode; returns the period in us until the next step. */
uint32_t agent_step(void);
/* A new link came up (TCP connection, port opened): sequence tracking restarts and HELLO goes out. */
void     agent_link_up(void);
/* The board's button (or any local safety input): surface now, as CMD_SURFACE does. */
void     agent_surface(void);

#endif
