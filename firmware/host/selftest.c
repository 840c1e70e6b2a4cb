/* selftest.c - a C-only smoke test of the portable firmware on the host (make host). */
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include "mixer.h"
#include "robot.h"
#include "stepper.h"
#include "swarm_coordinator.h"
#include "xbee_parser.h"

void fw_reset(void);
void fw_feed(const uint8_t *data, uint32_t n);
void fw_ticks(uint32_t n);
extern uint32_t host_tx_len;

static int failures;
static int checks;

#define CHECK(cond) do { checks++; if (!(cond)) { printf("FAIL %s:%d %s\n", __FILE__, \
    __LINE__, #cond); failures++; } } while (0)

/* An escaped 0x90 frame from addr carrying CMD_VEL seq 7, speed 300 (30 mm/s), alpha 90
 * deg; returns its length. The frame data holds 0x13 (XOFF) when addr does. */
static uint8_t cmd_vel_frame(const uint8_t addr[8], uint8_t *frame)
{
    uint8_t data[18] = { 0x90, 0, 0, 0, 0, 0, 0, 0, 0, 0xFF,
                         0xFE, 0x01, 0x01, 0x07, 0x01, 0x2C, 0x00, 0x5A };
    uint8_t n = 0;
    uint8_t i;
    uint8_t sum = 0;
    uint8_t b;
    memcpy(data + 1, addr, 8);
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
    return n;
}

int main(void)
{
    const uint8_t coordinator[8] = SWP_COORDINATOR_ADDR64;
    uint8_t stranger[8];
    uint8_t frame[2 * 18 + 8];
    uint8_t n;
    memcpy(stranger, coordinator, 8);
    stranger[7] ^= 0x01;   /* one bit away from the coordinator */
    fw_reset();
    /* a stranger's command: dropped unanswered, counted, flagged */
    n = cmd_vel_frame(stranger, frame);
    fw_feed(frame, n);
    CHECK(xp.frames == 1 && robot.foreign == 1);
    CHECK(st_rate[0] == 0 && st_rate[1] == 0 && st_rate[2] == 0);
    CHECK(host_tx_len == 0 && (robot.faults & SWP_FAULT_FOREIGN));
    /* the coordinator's */
    n = cmd_vel_frame(coordinator, frame);
    fw_feed(frame, n);
    CHECK(xp.frames == 2 && robot.foreign == 1);
    CHECK(robot.last_cmd_seq == 7);
    /* alpha = 90: V_A = v cos(60) = 150 units, V_B = v cos(-60) = 150, V_C = v cos(180) */
    CHECK(st_rate[0] == 337 && st_rate[1] == 337 && st_rate[2] == -674);
    CHECK(host_tx_len > 0); /* the ACK */
    fw_ticks(SWP_CMD_TIMEOUT_MS - 1);
    CHECK(st_rate[0] != 0);
    fw_ticks(1);
    CHECK(st_rate[0] == 0 && st_rate[1] == 0 && st_rate[2] == 0);
    CHECK(robot.faults & SWP_FAULT_WATCHDOG);
    printf("selftest: %d of %d checks passed\n", checks - failures, checks);
    return failures != 0;
}
