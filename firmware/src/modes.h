/* The mode machine (SPEC.md s. 6, 1.1 matrix): one control step per call, limits, episodes, samples. */
#ifndef MODES_H
#define MODES_H

#include <stdbool.h>
#include <stdint.h>

#include "params.h"

/* What the mode machine calls upward, wired by agent.c: the VALUES and POLICY dumps once an episode's
   planning is done (dump_each_episode). */
typedef void (*modes_episode_dumps_t)(void);

void     modes_init(modes_episode_dumps_t episode_dumps);
/* One control step of the current mode; returns the period in us until the next step. */
uint32_t modes_step(void);
uint8_t  modes_mode(void);
uint32_t modes_episode(void);
/* The learner generation (SPEC 1.3 s. 6): 1 at boot, +1 at every learner restart. */
uint32_t modes_generation(void);
uint32_t modes_next_sample(void);
/* Recovery steps that held the start depth because the last episode's planning was not done yet. */
uint32_t modes_plan_waits(void);
/* Episode starts that finished planning inside one step, making it late: 0 by construction (counted). */
uint32_t modes_forced_plans(void);

/* Commands: the verdict (value checks before mode checks); with apply set, also carried out. */
void modes_cmd_start(uint32_t max_episodes, bool apply, verdict_t *v);
void modes_cmd_stop(bool apply, verdict_t *v);
void modes_cmd_pause(bool apply, verdict_t *v);
void modes_cmd_surface(bool apply, verdict_t *v);
void modes_cmd_hover(float depth_m, bool apply, verdict_t *v);
void modes_cmd_reset_model(bool apply, verdict_t *v);
void modes_param_set(uint16_t index, uint64_t value_bits, bool apply, verdict_t *v);

#endif
