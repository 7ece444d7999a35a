/* The learner's state, on its own: learner.c (configuration, the arena, acting) and learner_plan.c (value
   iteration) both work on it, and keeping it here lets learner.c call planning without planning depending
   on learner.c in return. */
#include "learner_internal.h"

learner_state_t g_learner;
