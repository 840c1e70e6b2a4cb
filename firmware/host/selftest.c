/* selftest.c - a C-only smoke test of the portable firmware on the host (make host). */
#include <stdint.h>
#include <stdio.h>

#include "mixer.h"
#include "robot.h"
#include "stepper.h"
#include "xbee_parser.h"

void fw_reset(void);
void fw_feed(const uint8_t *data, uint32_t n);
void fw_ticks(uint32_t n);
extern uint32_t host_tx_len;

static int failures;

#define CHECK(cond) do { if (!(cond)) { printf("FAIL %s:%d %s\n", __FILE__, __LINE__, #cond); \
    failures++; } } while (0)

int main(void)
{
    /* 0x90 frame from 0013A20040A1B2C3: CMD_VEL seq 7, speed 300 (30 mm/s), alpha 90 deg.
     * The frame data holds 0x13 (XOFF), which API mode 2 escapes on the wire. */
    const uint8_t data[] = { 0x90, 0x00, 0x13, 0xA2, 0x00, 0x40, 0xA1, 0xB2, 0xC3, 0xFF,
                             0xFE, 0x01, 0x01, 0x07, 0x01, 0x2C, 0x00, 0x5A };
    uint8_t frame[2 * sizeof(data) + 8];
    uint8_t n = 0;
    uint8_t i;
    uint8_t sum = 0;
    uint8_t b;
    frame[n++] = SWP_XBEE_START;
    frame[n++] = 0x00;
    frame[n++] = (uint8_t)sizeof(data);
    for (i = 0; i <= sizeof(data); i++) {
        if (i < sizeof(data)) {
            b = data[i];
            sum += b;
        } else {
            b = (uint8_t)(0xFF - sum);
        }
        if (b == SWP_XBEE_START || b == SWP_XBEE_ESCAPE || b == SWP_XBEE_XON
            || b == SWP_XBEE_XOFF) {
            frame[n++] = SWP_XBEE_ESCAPE;
            b ^= SWP_XBEE_ESCAPE_XOR;
        }
        frame[n++] = b;
    }
    fw_reset();
    fw_feed(frame, n);
    CHECK(xp.frames == 1);
    CHECK(robot.last_cmd_seq == 7);
    /* alpha = 90: V_A = v cos(60) = 150 units, V_B = v cos(-60) = 150, V_C = v cos(180) */
    CHECK(st_rate[0] == 337 && st_rate[1] == 337 && st_rate[2] == -674);
    CHECK(host_tx_len > 0); /* the ACK */
    fw_ticks(SWP_CMD_TIMEOUT_MS - 1);
    CHECK(st_rate[0] != 0);
    fw_ticks(1);
    CHECK(st_rate[0] == 0 && st_rate[1] == 0 && st_rate[2] == 0);
    CHECK(robot.faults & SWP_FAULT_WATCHDOG);
    printf("selftest: %d of 7 checks passed\n", 7 - failures);
    return failures != 0;
}
