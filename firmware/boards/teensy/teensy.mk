# The Teensy 3.2 build (MK20DX256: Cortex-M4 without FPU, 256 KB flash, 64 KB RAM), included by firmware/Makefile.
#   make -C firmware teensy         -> every learner variant linked against Teensyduino's own teensy3 core and Wire
#                                      (startup, linker script mk20dx256.ld, USB serial, Serial1, Wire), as the
#                                      Arduino IDE or PlatformIO link them: build/teensy/<variant>/agent.elf and
#                                      agent.hex (for teensy_loader_cli); prints flash and RAM per variant and the
#                                      RAM left for stack and heap, and fails if that is less than TEENSY_STACK_BYTES.
#                                      The variants' learner storage fits the paper learner (S = 101), the
#                                      actuator-state learner (actuator3, S = 301), the shared-model learner with 13
#                                      actuator bins (shared-bins13, S = 1301) and the hardware preset's best, 20
#                                      depth cells and 7 bins (shared-z20, S = 1401).
#   make -C firmware teensy-sketch  -> copies the core into boards/teensy/diving_agent/src/core for Teensyduino
#                                      (Arduino IDE or platformio, boards/teensy/platformio.ini)
#
# The core is found through TEENSY_CORE_DIR (the teensy3 folder, with mk20dx256.ld) and TEENSY_LIBS_DIR (the folder
# holding Wire/). By default the first of: ../shared/vendor/teensyduino beside the repository (CI's copy), PlatformIO's
# framework-arduinoteensy, the Arduino IDE 2's Teensyduino board package (the newest; Linux, then macOS), the
# Teensyduino installer's copy inside an Arduino 1.8 folder (~/arduino-*, /opt/arduino-*). Where none is found, the
# variants link against compile_check/ (declarations and empty stubs): a size estimate whose image is not flashable,
# so no .hex is written (also with TEENSY_CORE_DIR set empty).

TEENSY_DIR := $(FIRMWARE)/boards/teensy
TEENSY_BUILD := $(BUILD)/teensy
ARM_CC ?= arm-none-eabi-gcc
ARM_CXX ?= arm-none-eabi-g++
ARM_AR ?= arm-none-eabi-ar
ARM_SIZE ?= arm-none-eabi-size
ARM_OBJCOPY ?= arm-none-eabi-objcopy
TEENSY_ARCH := -mcpu=cortex-m4 -mthumb -mfloat-abi=soft
# What Teensyduino defines for a Teensy 3.2 at 72 MHz with USB type "Serial" (its boards.txt / platform.txt).
TEENSY_DEFINES := -D__MK20DX256__ -DARDUINO_TEENSY32 -DF_CPU=72000000 -DUSB_SERIAL -DLAYOUT_US_ENGLISH \
	-DTEENSYDUINO=159 -DARDUINO=10813
TEENSY_COMMON := $(TEENSY_ARCH) -Os -g -ffunction-sections -fdata-sections -Wall -Wextra -Werror -Wdouble-promotion
TEENSY_CFLAGS := -std=c99 $(TEENSY_COMMON) -Wshadow $(INCLUDES)
# The stack and heap the agent needs above its static RAM: the core's stack peak measured on the emulated board
# (1 076 B, docs/firmware.md) with room for the Teensy core's interrupt handlers, which run on the same stack.
TEENSY_STACK_BYTES ?= 4096
ARENA_TOOL := $(BUILD)/host/arena_size
LEARNER_SRC := $(addprefix $(FIRMWARE)/src/,learner.c learner_model.c learner_plan.c learner_state.c shared.c shared_plan.c rng.c)
# name z_cells zdot_cells act_bins shared_model
TEENSY_VARIANTS := paper:10:10:1:0 actuator3:10:10:3:0 shared-bins13:10:10:13:1 shared-z20:20:10:7:1
SKETCH_DIR ?= $(FIRMWARE)/boards/teensy/diving_agent
SKETCH_CORE = $(SKETCH_DIR)/src/core

# ------------------------------------------------------------------ where the Teensyduino core is
TEENSY_VENDOR := $(abspath $(FIRMWARE)/../../shared/vendor/teensyduino)
TEENSY_CORE_SEARCH := $(TEENSY_VENDOR)/cores/teensy3 \
	$(HOME)/.platformio/packages/framework-arduinoteensy/cores/teensy3 \
	$(lastword $(sort $(wildcard $(HOME)/.arduino15/packages/teensy/hardware/avr/*/cores/teensy3))) \
	$(lastword $(sort $(wildcard $(HOME)/Library/Arduino15/packages/teensy/hardware/avr/*/cores/teensy3))) \
	$(lastword $(sort $(wildcard $(HOME)/arduino-*/hardware/teensy/avr/cores/teensy3 \
	    /opt/arduino-*/hardware/teensy/avr/cores/teensy3)))
ifeq ($(origin TEENSY_CORE_DIR),undefined)
TEENSY_CORE_DIR := $(firstword $(foreach d,$(TEENSY_CORE_SEARCH),$(if $(wildcard $(d)/mk20dx256.ld),$(d))))
else ifneq ($(TEENSY_CORE_DIR),)
ifeq ($(wildcard $(TEENSY_CORE_DIR)/mk20dx256.ld),)
$(error TEENSY_CORE_DIR=$(TEENSY_CORE_DIR) holds no mk20dx256.ld: give the teensy3 folder of a Teensyduino core)
endif
endif
# Every layout above keeps the libraries two levels above cores/teensy3.
TEENSY_LIBS_DIR ?= $(if $(TEENSY_CORE_DIR),$(abspath $(TEENSY_CORE_DIR)/../../libraries))
ifneq ($(TEENSY_CORE_DIR),)
ifeq ($(wildcard $(TEENSY_LIBS_DIR)/Wire/WireKinetis.cpp),)
$(error TEENSY_LIBS_DIR=$(TEENSY_LIBS_DIR) holds no Wire/WireKinetis.cpp: give the folder of Teensyduino's libraries)
endif
endif

.PHONY: teensy teensy-sketch teensy-variant teensy-core teensy-core-dir

# The core `make teensy` would link against (empty: none found, the stubs), for the tests and for a user who asks.
teensy-core-dir:
	@echo "$(TEENSY_CORE_DIR)"

$(ARENA_TOOL): $(TEENSY_DIR)/arena_size.c $(LEARNER_SRC) $(FIRMWARE)/src/learner.h
	@mkdir -p $(dir $@)
	$(HOST_CC) -std=c99 -O1 $(INCLUDES) $(TEENSY_DIR)/arena_size.c $(LEARNER_SRC) -lm -o $@

teensy: $(ARENA_TOOL) teensy-core
	@for v in $(TEENSY_VARIANTS); do \
	    set -- $$(echo $$v | tr ':' ' '); \
	    sizes=$$($(ARENA_TOOL) $$2 $$3 $$4 $$5) || exit 1; set -- $$1 $$sizes; \
	    $(MAKE) --no-print-directory -f $(FIRMWARE)/Makefile teensy-variant VARIANT=$$1 LEARNER_BYTES=$$2 \
	        DUMPS_BYTES=$$3 || exit 1; \
	done
ifneq ($(TEENSY_CORE_DIR),)
	@echo "Teensy 3.2 images (agent.elf, agent.hex) linked against"
	@echo "  core $(TEENSY_CORE_DIR)"
	@echo "  Wire $(TEENSY_LIBS_DIR)/Wire"
	@echo "flash = code + the data copied to RAM at reset; RAM = all static RAM, 0x1FFF8000 to _ebss (the core's"
	@echo "USB buffers, Serial and Wire included); free = _estack - _ebss: stack and heap (needed: $(TEENSY_STACK_BYTES) B)"
	@for v in $(TEENSY_VARIANTS); do \
	    name=$${v%%:*}; ARM_NM=$(ARM_NM) ARM_SIZE=$(ARM_SIZE) sh $(TEENSY_DIR)/image_size.sh \
	        $(TEENSY_BUILD)/$$name/agent.elf $$name $(TEENSY_STACK_BYTES) || failed=1; \
	done; exit $${failed:-0}
else
	@echo "teensy: no Teensyduino core found (set TEENSY_CORE_DIR / TEENSY_LIBS_DIR): linked against compile_check/ stubs, NOT flashable, no .hex"
	@$(ARM_SIZE) $(foreach v,$(TEENSY_VARIANTS),$(TEENSY_BUILD)/$(firstword $(subst :, ,$(v)))/agent.elf)
endif

# One variant: learner and snapshot storage sized to LEARNER_BYTES / DUMPS_BYTES.
TEENSY_VARIANT_DIR = $(TEENSY_BUILD)/$(VARIANT)
TEENSY_CORE_SRC := $(filter-out %/learner.c,$(CORE_SRC)) $(FIRMWARE)/src/learner.c
teensy-variant:
	@rm -rf $(TEENSY_VARIANT_DIR) && mkdir -p $(TEENSY_VARIANT_DIR)
	cd $(TEENSY_VARIANT_DIR) && $(ARM_CC) $(TEENSY_CFLAGS) -DLEARNER_ARENA_BYTES=$(LEARNER_BYTES)u \
	    -DDUMPS_ARENA_BYTES=$(DUMPS_BYTES)u -c $(TEENSY_CORE_SRC)
	$(MAKE) --no-print-directory -f $(FIRMWARE)/Makefile teensy-sketch SKETCH_DIR=$(TEENSY_VARIANT_DIR)/sketch >/dev/null
	$(ARM_CXX) $(TEENSY_SKETCH_CXXFLAGS) -x c++ -c $(TEENSY_VARIANT_DIR)/sketch/diving_agent.ino \
	    -o $(TEENSY_VARIANT_DIR)/diving_agent.o
ifneq ($(TEENSY_CORE_DIR),)
	$(ARM_CC) $(TEENSY_LDFLAGS) $(TEENSY_VARIANT_DIR)/*.o $(TEENSY_CORE_LIB) -lm -o $(TEENSY_VARIANT_DIR)/agent.elf
	$(ARM_OBJCOPY) -O ihex -R .eeprom $(TEENSY_VARIANT_DIR)/agent.elf $(TEENSY_VARIANT_DIR)/agent.hex
else
	$(ARM_CXX) $(TEENSY_SKETCH_CXXFLAGS) -c $(TEENSY_STUBS)/link_stubs.cpp -o $(TEENSY_VARIANT_DIR)/link_stubs.o
	$(ARM_CXX) $(TEENSY_LDFLAGS) $(TEENSY_VARIANT_DIR)/*.o -lm -o $(TEENSY_VARIANT_DIR)/agent.elf
endif

# ------------------------------------------------------------------ the sketch's flags, the core library
ARM_NM ?= arm-none-eabi-nm
TEENSY_STUBS := $(TEENSY_DIR)/compile_check
ifneq ($(TEENSY_CORE_DIR),)
# The core and Wire are built as Teensyduino builds them (its own warnings are its own: no -Werror there), into one
# archive, so that the link takes only the members the agent uses, as the Arduino IDE's core.a does. Their headers
# are system headers for the sketch, so -Werror holds the sketch's own code and not the core's.
TEENSY_CORE_FLAGS := $(TEENSY_ARCH) $(TEENSY_DEFINES) -Os -g -Wall -ffunction-sections -fdata-sections \
	-I$(TEENSY_CORE_DIR) -I$(TEENSY_LIBS_DIR)/Wire
TEENSY_CORE_CXX := -std=gnu++17 -felide-constructors -fno-exceptions -fno-rtti
TEENSY_SKETCH_CXXFLAGS := -std=gnu++17 $(TEENSY_COMMON) $(TEENSY_DEFINES) -felide-constructors -fno-exceptions \
	-fno-rtti -isystem $(TEENSY_CORE_DIR) -isystem $(TEENSY_LIBS_DIR)/Wire
TEENSY_LDFLAGS := $(TEENSY_ARCH) -Os -T $(TEENSY_CORE_DIR)/mk20dx256.ld --specs=nano.specs \
	-Wl,--gc-sections,--defsym=__rtc_localtime=0
TEENSY_CORE_OBJ := $(patsubst $(TEENSY_CORE_DIR)/%,$(TEENSY_BUILD)/core/%.o,\
	$(wildcard $(TEENSY_CORE_DIR)/*.c $(TEENSY_CORE_DIR)/*.cpp $(TEENSY_CORE_DIR)/*.S)) \
	$(patsubst $(TEENSY_LIBS_DIR)/Wire/%,$(TEENSY_BUILD)/wire/%.o,$(wildcard $(TEENSY_LIBS_DIR)/Wire/*.cpp))
TEENSY_CORE_LIB := $(TEENSY_BUILD)/core.a

teensy-core: $(TEENSY_CORE_LIB)

$(TEENSY_CORE_LIB): $(TEENSY_CORE_OBJ)
	@rm -f $@ && $(ARM_AR) rcs $@ $^
$(TEENSY_BUILD)/core/%.c.o: $(TEENSY_CORE_DIR)/%.c
	@mkdir -p $(dir $@) && $(ARM_CC) $(TEENSY_CORE_FLAGS) -c $< -o $@
$(TEENSY_BUILD)/core/%.cpp.o: $(TEENSY_CORE_DIR)/%.cpp
	@mkdir -p $(dir $@) && $(ARM_CXX) $(TEENSY_CORE_FLAGS) $(TEENSY_CORE_CXX) -c $< -o $@
$(TEENSY_BUILD)/core/%.S.o: $(TEENSY_CORE_DIR)/%.S
	@mkdir -p $(dir $@) && $(ARM_CC) $(TEENSY_CORE_FLAGS) -x assembler-with-cpp -c $< -o $@
$(TEENSY_BUILD)/wire/%.cpp.o: $(TEENSY_LIBS_DIR)/Wire/%.cpp
	@mkdir -p $(dir $@) && $(ARM_CXX) $(TEENSY_CORE_FLAGS) $(TEENSY_CORE_CXX) -c $< -o $@
else
TEENSY_SKETCH_CXXFLAGS := -std=gnu++17 $(TEENSY_COMMON) -fno-exceptions -fno-rtti -I$(TEENSY_STUBS)
TEENSY_LDFLAGS := $(TEENSY_ARCH) -T $(TEENSY_STUBS)/mk20dx256.ld -nostartfiles --specs=nano.specs \
	--specs=nosys.specs -Wl,--gc-sections

teensy-core:
endif

teensy-sketch:
	rm -rf $(SKETCH_CORE) && mkdir -p $(SKETCH_CORE)
	[ $(abspath $(SKETCH_DIR)) = $(TEENSY_DIR)/diving_agent ] || cp $(TEENSY_DIR)/diving_agent/diving_agent.ino $(SKETCH_DIR)/
	cp $(filter-out %/plant.c %/sensor.c,$(wildcard $(FIRMWARE)/src/*.[ch])) $(FIRMWARE)/include/hal.h \
	    $(wildcard $(FIRMWARE)/generated/*.[ch]) $(SKETCH_CORE)/
	@echo "core copied to $(SKETCH_CORE): open boards/teensy/diving_agent in the Arduino IDE, or run pio run in boards/teensy"
