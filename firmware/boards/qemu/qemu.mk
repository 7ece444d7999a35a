# The emulated Cortex-M4 build (QEMU mps2-an386), included by firmware/Makefile.
#   make -C firmware qemu      -> build/qemu/agent.elf (core + learner + C plant and sensor + this board)
#   make -C firmware qemu-run  -> runs it with the link on tcp://127.0.0.1:$(QEMU_PORT)
# Same flags as the Teensy build: Cortex-M4 without FPU, soft float, newlib-nano, no semihosting.

QEMU_BOARD_DIR := boards/qemu
QEMU_BUILD_DIR := build/qemu
QEMU_ELF := $(QEMU_BUILD_DIR)/agent.elf
QEMU_PORT ?= 5760
ARM_CC ?= arm-none-eabi-gcc
ARM_SIZE ?= arm-none-eabi-size
QEMU_SYSTEM ?= qemu-system-arm

# The water: double-precision plant and sensor, only on the emulated board (never in the Teensy core).
CTL_SIM_SRCS := src/plant.c src/sensor.c
QEMU_CORE_SRCS := $(filter-out $(CTL_SIM_SRCS),$(wildcard src/*.c)) $(wildcard generated/*.c)
QEMU_SRCS := $(QEMU_CORE_SRCS) $(CTL_SIM_SRCS) $(wildcard $(QEMU_BOARD_DIR)/*.c)
QEMU_OBJS := $(patsubst %.c,$(QEMU_BUILD_DIR)/%.o,$(QEMU_SRCS))

QEMU_ARCH := -mcpu=cortex-m4 -mthumb -mfloat-abi=soft
QEMU_CFLAGS := -std=c99 $(QEMU_ARCH) -O2 -g -MMD -MP -Wall -Wextra -Werror -Wdouble-promotion -Wshadow -ffunction-sections -fdata-sections \
	-Isrc -Iinclude -Igenerated -I$(QEMU_BOARD_DIR) $(QEMU_EXTRA_CFLAGS)
QEMU_LDFLAGS := $(QEMU_ARCH) -T $(QEMU_BOARD_DIR)/mps2_an386.ld -nostartfiles --specs=nano.specs \
	--specs=nosys.specs -Wl,--gc-sections -Wl,-Map=$(QEMU_BUILD_DIR)/agent.map

.PHONY: qemu qemu-run qemu-size

-include $(QEMU_OBJS:.o=.d)

qemu: $(QEMU_ELF)

$(QEMU_BUILD_DIR)/%.o: %.c
	@mkdir -p $(dir $@)
	$(ARM_CC) $(QEMU_CFLAGS) -c $< -o $@

$(QEMU_ELF): $(QEMU_OBJS) $(QEMU_BOARD_DIR)/mps2_an386.ld
	$(ARM_CC) $(QEMU_LDFLAGS) $(QEMU_OBJS) -lm -o $@
	$(ARM_SIZE) $@

qemu-size: $(QEMU_ELF)
	$(ARM_SIZE) -A $(QEMU_ELF)

qemu-run: $(QEMU_ELF)
	$(QEMU_SYSTEM) -M mps2-an386 -nographic -monitor none -kernel $(QEMU_ELF) \
		-serial tcp:127.0.0.1:$(QEMU_PORT),server=on,wait=off -serial null
