/* The hardware layer: the only things a board provides to the core (Teensy 3.2, host library, QEMU). */
#ifndef HAL_H
#define HAL_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

uint64_t hal_time_us(void);                 /* agent clock */
uint64_t hal_link_time_us(void);            /* real time of the link (== hal_time_us on hardware) */
float    hal_pressure_pa(void);             /* one MS5803 reading, Pa */
void     hal_stepper_set_cmd_deg(float deg);/* commanded gear angle; the board moves toward it */
float    hal_stepper_deg(void);             /* motor-side angle now (counted steps, not the output) */
float    hal_battery_v(void);
size_t   hal_link_read(uint8_t *buf, size_t cap);   /* non-blocking */
void     hal_link_write(const uint8_t *buf, size_t n);
bool     hal_log_read(uint32_t addr, uint8_t *buf, size_t n);  /* the 512 KiB EEPROM log */
bool     hal_log_write(uint32_t addr, const uint8_t *buf, size_t n);
uint32_t hal_log_capacity_bytes(void);
bool     hal_nv_read(uint8_t *buf, size_t n);       /* small non-volatile area (signing mark) */
bool     hal_nv_write(const uint8_t *buf, size_t n);
uint32_t hal_entropy(void);
bool     hal_sim_place(float depth_m);      /* simulator only: put the plant at depth at rest; false on hardware */

#endif
