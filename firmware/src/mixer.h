/* mixer.h - command mixing of eqs. 5.1-5.3 in fixed point (no floating point). */
#ifndef MIXER_H
#define MIXER_H

#include <stdint.h>

#include "swarm_protocol.h"

/* Wheel rates of the last mix, half-steps per second, signed (A, B, C). */
extern int16_t mix_rate[3];

/* a * b, 16 x 16 -> 32 bits, by shift and add (no library multiply on the PIC14). */
uint32_t mul_u16(uint16_t a, uint16_t b);
/* Magnitude of sin(deg) in Q15 for deg 0..359; sets *negative when sin(deg) < 0. */
uint16_t sin_q15(uint16_t deg, uint8_t *negative);
/* Mix speed (0.1 mm/s units) and direction alpha (deg, clockwise from forward) into
 * mix_rate[]: rate_i = round(round(speed cos(phi_i - alpha)) * steps per unit), clipped to
 * +-SWP_MAX_STEP_RATE. Returns 1 when a rate was clipped. */
uint8_t mixer_mix(uint16_t speed, uint16_t alpha);

#endif
