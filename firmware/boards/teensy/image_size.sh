#!/bin/sh
# Flash and RAM of one Teensy 3.2 image linked with Teensyduino's mk20dx256.ld, and the RAM left for stack and heap.
# Usage: image_size.sh AGENT_ELF VARIANT STACK_BYTES; exits 1 when the free RAM is less than STACK_BYTES.
# Read from the linker script's own symbols, not from `size`'s Berkeley columns: those count .data as text (it holds
# .fastrun code) and know nothing of the stack, which mk20dx256.ld does not reserve: it grows down from _estack
# towards the heap, which starts at _ebss (the core's _sbrk).
set -eu
elf=$1 variant=$2 stack_bytes=$3
NM=${ARM_NM:-arm-none-eabi-nm}
SIZE=${ARM_SIZE:-arm-none-eabi-size}
FLASH_BYTES=262144
RAM_BYTES=65536
RAM_ORIGIN=$((0x1FFF8000))

symbol() {  # the address of a linker-script symbol, in decimal
    value=$("$NM" "$elf" | awk -v s="$1" '$3 == s { print $1; exit }')
    [ -n "$value" ] || { echo "teensy: $elf has no symbol $1: not linked with Teensyduino's mk20dx256.ld" >&2; exit 1; }
    echo $((0x$value))
}

etext=$(symbol _etext)
ebss=$(symbol _ebss)
estack=$(symbol _estack)
# section sizes in decimal (size -A): .data is stored in flash after _etext and copied to RAM at reset
sections=$("$SIZE" -A -d "$elf")
section() { echo "$sections" | awk -v s="$1" '$1 == s { print $2; found = 1 } END { if (!found) print 0 }'; }
data=$(section .data)
usb=$(( $(section .usbdescriptortable) + $(section .dmabuffers) + $(section .usbbuffers) ))
bss=$(section .bss)
flash=$((etext + data))
ram=$((ebss - RAM_ORIGIN))
free=$((estack - ebss))
percent() { awk -v a="$1" -v b="$2" 'BEGIN { printf "%.1f", 100 * a / b }'; }
printf '%-14s flash %6d B (%4s %% of 256 KB)  RAM %6d B (%4s %% of 64 KB: USB %d, data %d, bss %d)  free for stack and heap %6d B\n' \
    "$variant" "$flash" "$(percent "$flash" $FLASH_BYTES)" "$ram" "$(percent "$ram" $RAM_BYTES)" "$usb" "$data" "$bss" "$free"
if [ "$free" -lt "$stack_bytes" ]; then
    echo "teensy: $variant leaves $free B for stack and heap, less than the $stack_bytes B it needs (TEENSY_STACK_BYTES)" >&2
    exit 1
fi
