/* stepper.c - step timing by phase accumulation: a channel with rate r half-steps/s
 * steps exactly r times per SWP_TICK_HZ ticks, evenly spread (Bresenham / DDS). */
#include "stepper.h"

/* Half-step sequence of a unipolar stepper on a ULN2003 (IN1..IN4 = bits 0..3):
 * 0x01 0x03 0x02 0x06 0x04 0x0C 0x08 0x09. Computed in stepper_tick, not read from a const
 * table: sdcc's pic14 port reads code-space tables through a library call, one level of
 * the 8-level hardware stack the timer interrupt cannot spare. Even phases drive coil
 * phase/2, odd ones that coil and the next. */

int16_t st_rate[3];
uint16_t st_acc[3];
uint8_t st_phase[3];
uint8_t st_coils[3];
#if !defined(__SDCC)
int32_t st_position[3];
#endif

void stepper_init(void)
{
    uint8_t i;
    for (i = 0; i < 3; i++) {
        st_rate[i] = 0;
        st_acc[i] = 0;
        st_phase[i] = 0;
        st_coils[i] = 0;
#if !defined(__SDCC)
        st_position[i] = 0;
#endif
    }
}

void stepper_tick(void)
{
    uint8_t i;
    int16_t rate;
    uint16_t magnitude;
    uint8_t phase;
    uint8_t coil;
    for (i = 0; i < 3; i++) {
        rate = st_rate[i];
        if (rate == 0) {
            st_coils[i] = 0; /* release the coils: no holding current while stopped */
            continue;
        }
        magnitude = rate < 0 ? (uint16_t)(-rate) : (uint16_t)rate;
        st_acc[i] += magnitude;
        if (st_acc[i] >= SWP_TICK_HZ) {
            st_acc[i] -= SWP_TICK_HZ;
            if (rate > 0) {
                st_phase[i] = (st_phase[i] + 1) & 7;
#if !defined(__SDCC)
                st_position[i]++;
#endif
            } else {
                st_phase[i] = (st_phase[i] - 1) & 7;
#if !defined(__SDCC)
                st_position[i]--;
#endif
            }
        }
        phase = st_phase[i];
        coil = (uint8_t)(1u << (phase >> 1));
        if (phase & 1) {
            coil |= (uint8_t)(((coil << 1) | (coil >> 3)) & 0x0F);
        }
        st_coils[i] = coil;
    }
}
