/* mixer.c - command mixture of the thesis (Figure 5.6, eqs. 5.1-5.3), fixed point.
 *
 *   V_A = |Vel| cos(150 - alpha)   (5.1)
 *   V_B = |Vel| cos( 30 - alpha)   (5.2)
 *   V_C = |Vel| cos(270 - alpha)   (5.3)
 *
 * cos(x) = sin(x + 90) from a quarter-wave Q15 table; every product is rounded half up.
 * swarm_bridge/protocol.py:mix_fixed() is the bit-exact Python twin (tested).
 */
#include "mixer.h"

static const uint16_t SIN_TABLE[SWP_SIN_TABLE_LEN] = SWP_SIN_Q15_TABLE;
static const uint16_t WHEEL_PHI[3] = { SWP_WHEEL_PHI_A, SWP_WHEEL_PHI_B, SWP_WHEEL_PHI_C };

int16_t mix_rate[3];

uint32_t mul_u16(uint16_t a, uint16_t b)
{
    uint32_t acc = 0;
    uint32_t addend = a;
    while (b != 0) {
        if (b & 1) {
            acc += addend;
        }
        addend <<= 1;
        b >>= 1;
    }
    return acc;
}

uint16_t sin_q15(uint16_t deg, uint8_t *negative)
{
    *negative = 0;
    if (deg >= 180) {
        *negative = 1;
        deg -= 180;
    }
    if (deg > 90) {
        deg = 180 - deg;
    }
    return SIN_TABLE[deg];
}

uint8_t mixer_mix(uint16_t speed, uint16_t alpha)
{
    uint8_t i;
    uint8_t negative;
    uint8_t clipped = 0;
    uint16_t angle;
    uint16_t wheel;
    uint16_t rate;
    for (i = 0; i < 3; i++) {
        /* cos(phi - alpha) = sin(phi - alpha + 90), angle kept in 0..359 */
        angle = WHEEL_PHI[i] + 90 + SWP_DIRECTION_FULL_TURN - alpha;
        while (angle >= SWP_DIRECTION_FULL_TURN) {
            angle -= SWP_DIRECTION_FULL_TURN;
        }
        /* sin_q15(angle) written out: one call level less (the PIC's 8-level stack) */
        negative = 0;
        if (angle >= 180) {
            negative = 1;
            angle -= 180;
        }
        if (angle > 90) {
            angle = 180 - angle;
        }
        wheel = (uint16_t)((mul_u16(speed, SIN_TABLE[angle])
                            + (1UL << (SWP_SIN_SHIFT - 1))) >> SWP_SIN_SHIFT);
        {
            uint32_t steps = (mul_u16(wheel, SWP_STEPS_PER_UNIT_Q12)
                              + (1UL << (SWP_STEPS_SHIFT - 1))) >> SWP_STEPS_SHIFT;
            if (steps > SWP_MAX_STEP_RATE) {
                steps = SWP_MAX_STEP_RATE;
                clipped = 1;
            }
            rate = (uint16_t)steps;
        }
        mix_rate[i] = negative ? -(int16_t)rate : (int16_t)rate;
    }
    return clipped;
}
