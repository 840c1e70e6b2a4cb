/* stepper.h - three half-stepping channels timed from wheel rates (hardware independent). */
#ifndef STEPPER_H
#define STEPPER_H

#include <stdint.h>

#include "swarm_protocol.h"

extern int16_t st_rate[3];     /* half-steps per second, signed; written under HAL_CRITICAL */
extern uint16_t st_acc[3];     /* phase accumulators, 0..SWP_TICK_HZ-1                     */
extern uint8_t st_phase[3];    /* index into the half-step sequence, 0..7                  */
/* Coil pattern of each channel after the last tick (bits 0..3 = IN1..IN4 of its ULN2003),
 * 0: off; hal_coils() drives them. A byte array, so the timer interrupt indexes no 16-bit
 * array (a library multiply and one more level of the PIC's 8-level stack). */
extern uint8_t st_coils[3];
#if !defined(__SDCC)
extern int32_t st_position[3]; /* half-steps taken, signed (host builds: tests only)       */
#endif

void stepper_init(void);
/* One timer tick (1/SWP_TICK_HZ s): advance each channel whose accumulator overflows. */
void stepper_tick(void);

#endif
