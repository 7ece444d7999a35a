# The Teensy 3.2 build (MK20DX256: Cortex-M4 without FPU, 256 KB flash, 64 KB RAM), included by firmware/Makefile.
#   make -C firmware teensy         -> the core + the sketch's glue, compiled with arm-none-eabi-gcc and linked
#                                      against compile_check/ (declarations and empty stubs of the Arduino calls),
#                                      in four variants whose learner storage fits the paper learner (S = 101),
#                                      the actuator-state learner (actuator3, S = 301), the shared-model
#                                      learner with 13 actuator bins (shared-bins13, S = 1301) and the hardware
#                                      preset's best, 20 depth cells and 7 bins (shared-z20, S = 1401); prints
#                                      arm-none-eabi-size
#   make -C firmware teensy-sketch  -> copies the core into boards/teensy/diving_agent/src/core for Teensyduino
#                                      (Arduino IDE or platformio, boards/teensy/platformio.ini)

TEENSY_DIR := $(FIRMWARE)/boards/teensy
TEENSY_BUILD := $(BUILD)/teensy
ARM_CC ?= arm-none-eabi-gcc
ARM_CXX ?= arm-none-eabi-g++
ARM_SIZE ?= arm-none-eabi-size
TEENSY_ARCH := -mcpu=cortex-m4 -mthumb -mfloat-abi=soft
TEENSY_COMMON := $(TEENSY_ARCH) -Os -g -ffunction-sections -fdata-sections -Wall -Wextra -Werror -Wdouble-promotion
TEENSY_CFLAGS := -std=c99 $(TEENSY_COMMON) -Wshadow $(INCLUDES)
TEENSY_CXXFLAGS := -std=gnu++17 $(TEENSY_COMMON) -fno-exceptions -fno-rtti -I$(TEENSY_DIR)/compile_check
TEENSY_LDFLAGS := $(TEENSY_ARCH) -T $(TEENSY_DIR)/mk20dx256.ld -nostartfiles --specs=nano.specs --specs=nosys.specs \
	-Wl,--gc-sections
TEENSY_CORE := $(filter-out %/learner.c,$(CORE_SRC)) $(FIRMWARE)/src/learner.c
ARENA_TOOL := $(BUILD)/host/arena_size
LEARNER_SRC := $(addprefix $(FIRMWARE)/src/,learner.c learner_model.c learner_plan.c learner_state.c shared.c shared_plan.c rng.c)
# name z_cells zdot_cells act_bins shared_model
TEENSY_VARIANTS := paper:10:10:1:0 actuator3:10:10:3:0 shared-bins13:10:10:13:1 shared-z20:20:10:7:1
SKETCH_DIR ?= $(TEENSY_DIR)/diving_agent
SKETCH_CORE = $(SKETCH_DIR)/src/core

.PHONY: teensy teensy-sketch teensy-variant

$(ARENA_TOOL): $(TEENSY_DIR)/arena_size.c $(LEARNER_SRC) $(FIRMWARE)/src/learner.h
	@mkdir -p $(dir $@)
	$(HOST_CC) -std=c99 -O1 $(INCLUDES) $(TEENSY_DIR)/arena_size.c $(LEARNER_SRC) -lm -o $@

teensy: $(ARENA_TOOL)
	@for v in $(TEENSY_VARIANTS); do \
	    set -- $$(echo $$v | tr ':' ' '); \
	    sizes=$$($(ARENA_TOOL) $$2 $$3 $$4 $$5) || exit 1; set -- $$1 $$sizes; \
	    $(MAKE) --no-print-directory -f $(FIRMWARE)/Makefile teensy-variant VARIANT=$$1 LEARNER_BYTES=$$2 \
	        DUMPS_BYTES=$$3 || exit 1; \
	done
	@echo "flash = text + data, RAM = data + bss (the stack reserve, 4096 B, is in bss: section .stack)"
	@$(ARM_SIZE) $(foreach v,$(TEENSY_VARIANTS),$(TEENSY_BUILD)/$(firstword $(subst :, ,$(v)))/agent.elf)

# One variant: learner and snapshot storage sized to LEARNER_BYTES / DUMPS_BYTES.
TEENSY_VARIANT_DIR = $(TEENSY_BUILD)/$(VARIANT)
teensy-variant:
	@mkdir -p $(TEENSY_VARIANT_DIR)
	cd $(TEENSY_VARIANT_DIR) && $(ARM_CC) $(TEENSY_CFLAGS) -DLEARNER_ARENA_BYTES=$(LEARNER_BYTES)u \
	    -DDUMPS_ARENA_BYTES=$(DUMPS_BYTES)u -c $(TEENSY_CORE)
	$(MAKE) --no-print-directory -f $(FIRMWARE)/Makefile teensy-sketch SKETCH_DIR=$(TEENSY_VARIANT_DIR)/sketch >/dev/null
	$(ARM_CXX) $(TEENSY_CXXFLAGS) -x c++ -c $(TEENSY_VARIANT_DIR)/sketch/diving_agent.ino \
	    -o $(TEENSY_VARIANT_DIR)/diving_agent.o
	$(ARM_CXX) $(TEENSY_CXXFLAGS) -c $(TEENSY_DIR)/compile_check/link_stubs.cpp -o $(TEENSY_VARIANT_DIR)/link_stubs.o
	$(ARM_CXX) $(TEENSY_LDFLAGS) $(TEENSY_VARIANT_DIR)/*.o -lm -o $(TEENSY_VARIANT_DIR)/agent.elf

teensy-sketch:
	rm -rf $(SKETCH_CORE) && mkdir -p $(SKETCH_CORE)
	[ $(abspath $(SKETCH_DIR)) = $(TEENSY_DIR)/diving_agent ] || cp $(TEENSY_DIR)/diving_agent/diving_agent.ino $(SKETCH_DIR)/
	cp $(filter-out %/plant.c %/sensor.c,$(wildcard $(FIRMWARE)/src/*.[ch])) $(FIRMWARE)/include/hal.h \
	    $(wildcard $(FIRMWARE)/generated/*.[ch]) $(SKETCH_CORE)/
	@echo "core copied to $(SKETCH_CORE): open boards/teensy/diving_agent in the Arduino IDE, or run pio run in boards/teensy"
