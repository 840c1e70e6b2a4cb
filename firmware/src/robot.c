/* robot.c - the board's application layer (see PROTOCOL.md).
 *
 * Only 0x90 frames from the coordinator's 64-bit address (SWP_COORDINATOR_ADDR64, set at
 * build time from the fleet file) are obeyed; any other sender's frame is dropped
 * unanswered and counted (robot.foreign, status byte 13, fault SWP_FAULT_FOREIGN).
 * A valid CMD_VEL is mixed into three wheel rates (eqs. 5.1-5.3, mixer.c) and applied
 * to the stepper channels; STOP zeroes them. Every command is acknowledged. The command
 * watchdog in robot_tick() zeroes the rates SWP_CMD_TIMEOUT_MS after the last valid
 * command, so a robot whose link dies stops within 500 ms whatever the main loop does.
 */
#include "robot.h"

#include "hal.h"
#include "mixer.h"
#include "stepper.h"
#include "swarm_coordinator.h" /* generated in the build directory (Makefile) */
#include "xbee_parser.h"

robot_t robot;

/* Call depth: the PIC16F690 has an 8-level hardware stack, shared by the main loop and
 * the interrupt (its entry plus isr -> robot_tick -> stepper_tick: 3 levels, or isr ->
 * robot_rx_isr -> xp_feed). So the main loop must stay within 5 levels below main():
 * frames go out from robot_poll -> send_payload -> put_escaped -> hal_uart_put, and
 * handle_frame only fills robot.tx with the acknowledgement (robot_poll -> handle_frame
 * -> mixer_mix -> code-table read, 2 library levels, is the deepest main-loop chain).
 * tests/unit/bridge/test_gpsim.py runs the build in gpsim, which halts on an overflow.
 *
 * Interrupt rule: everything the interrupt calls takes at most one byte of arguments and
 * returns at most one byte (both in W). sdcc's pic14 port passes the other bytes, and its
 * library routines keep their temporaries, in the STK00.. registers, which the interrupt
 * does not save: a two-argument hal_coils(ch, pattern) here once overwrote the code
 * address the main loop's table read (__gptrget2) held in STK00 (PROTOCOL.md). */

static void put_escaped(uint8_t byte)
{
    if (byte == SWP_XBEE_START || byte == SWP_XBEE_ESCAPE || byte == SWP_XBEE_XON
            || byte == SWP_XBEE_XOFF) {
        hal_uart_put(SWP_XBEE_ESCAPE);
        byte ^= SWP_XBEE_ESCAPE_XOR;
    }
    hal_uart_put(byte);
}

/* Send robot.tx[0..len) to robot.host in a 0x10 transmit request (frame id 0: no status).
 * The checksum is summed here, not in a put_data() helper: one stack level less. */
static void send_payload(uint8_t len)
{
    uint8_t i;
    uint8_t sum;
    hal_uart_put(SWP_XBEE_START);
    put_escaped(0);
    put_escaped(SWP_TX_HEADER_LEN + len);
    put_escaped(SWP_API_TX_REQUEST);
    put_escaped(0); /* frame id */
    sum = (uint8_t)(SWP_API_TX_REQUEST + (SWP_ADDR16_UNKNOWN >> 8) + (SWP_ADDR16_UNKNOWN & 0xFF));
    for (i = 0; i < 8; i++) {
        sum += robot.host[i];
        put_escaped(robot.host[i]);
    }
    put_escaped(SWP_ADDR16_UNKNOWN >> 8);
    put_escaped(SWP_ADDR16_UNKNOWN & 0xFF);
    put_escaped(0); /* broadcast radius: maximum hops */
    put_escaped(0); /* options */
    for (i = 0; i < len; i++) {
        sum += robot.tx[i];
        put_escaped(robot.tx[i]);
    }
    put_escaped(SWP_XBEE_CHECKSUM_OK - sum);
}

/* Put an acknowledgement in robot.tx; the caller sends it (send_payload(SWP_LEN_ACK)). */
static uint8_t set_ack(uint8_t seq, uint8_t type, uint8_t result)
{
    robot.tx[0] = SWP_MSG_ACK;
    robot.tx[1] = seq;
    robot.tx[2] = type;
    robot.tx[3] = result;
    return 1;
}

static void set_fault(uint8_t flags)
{
    HAL_CRITICAL_BEGIN();
    robot.faults |= flags;
    HAL_CRITICAL_END();
}

/* Apply mix_rate[] (or zero) and restart the command watchdog. */
static void apply(uint8_t run)
{
    uint8_t i;
    HAL_CRITICAL_BEGIN();
    for (i = 0; i < 3; i++) {
        st_rate[i] = run ? mix_rate[i] : 0;
    }
    robot.running = run && (mix_rate[0] != 0 || mix_rate[1] != 0 || mix_rate[2] != 0);
    robot.cmd_age_ms = 0;
    robot.faults &= (uint8_t)~SWP_FAULT_WATCHDOG;
    HAL_CRITICAL_END();
}

/* Main loop: take the frame out of the parser's mailbox, then act on it. The mailbox
 * is released before anything is sent, so the interrupt can parse the next frame
 * while the (blocking) acknowledgement goes out. Returns 1 when robot.tx holds an
 * acknowledgement to send. */
static uint8_t handle_frame(void)
{
    uint8_t len;
    uint8_t i;
    uint8_t type;
    uint8_t seq;
    uint16_t speed;
    uint16_t alpha;
    if (xp.buf[0] != SWP_API_RX_PACKET || xp.length < SWP_RX_HEADER_LEN) {
        xp.ready = 0;
        return 0; /* modem status, transmit status: from our own XBee, nothing to do */
    }
    for (i = 0; i < 8; i++) {
        /* the sender's 64-bit address must be the coordinator's; unsigned index (see
         * xbee_parser.c). Dropped unanswered: an ack would tell a stranger it was heard. */
        if (xp.buf[(uint8_t)(i + 1)] != robot.host[i]) {
            xp.ready = 0;
            robot.foreign++;
            set_fault(SWP_FAULT_FOREIGN);
            return 0;
        }
    }
    len = xp.length - SWP_RX_HEADER_LEN;
    if (len < 2) {
        xp.ready = 0;
        return 0; /* no message: nothing to do */
    }
    type = xp.buf[XP_MSG];
    seq = xp.buf[XP_MSG + 1];
    speed = ((uint16_t)xp.buf[XP_MSG + 2] << 8) | xp.buf[XP_MSG + 3];
    alpha = ((uint16_t)xp.buf[XP_MSG + 4] << 8) | xp.buf[XP_MSG + 5];
    xp.ready = 0;
    if (type == SWP_MSG_CMD_VEL) {
        if (len != SWP_LEN_CMD_VEL) {
            set_fault(SWP_FAULT_BAD_MSG);
            return set_ack(seq, type, SWP_ACK_BAD_LENGTH);
        }
        if (alpha >= SWP_DIRECTION_FULL_TURN) {
            set_fault(SWP_FAULT_BAD_MSG);
            return set_ack(seq, type, SWP_ACK_BAD_VALUE);
        }
        if (mixer_mix(speed, alpha)) {
            set_fault(SWP_FAULT_RATE_LIMIT);
        }
        apply(1);
    } else if (type == SWP_MSG_STOP) {
        if (len != SWP_LEN_STOP) {
            set_fault(SWP_FAULT_BAD_MSG);
            return set_ack(seq, type, SWP_ACK_BAD_LENGTH);
        }
        apply(0);
    } else {
        set_fault(SWP_FAULT_BAD_MSG);
        return set_ack(seq, type, SWP_ACK_UNKNOWN_TYPE);
    }
    robot.last_cmd_seq = seq;
    return set_ack(seq, type, SWP_ACK_OK);
}

void robot_init(void)
{
    uint8_t i;
    static const uint8_t COORDINATOR[8] = SWP_COORDINATOR_ADDR64;
    xp_reset();
    stepper_init();
    robot.cmd_age_ms = 0xFFFF;
    robot.heartbeat_ms = 0;
    robot.heartbeat_due = 0;
    robot.faults = SWP_FAULT_RESET;
    robot.status_seq = 0;
    robot.last_cmd_seq = 0;
    robot.running = 0;
    robot.foreign = 0;
    for (i = 0; i < 8; i++) {
        robot.host[i] = COORDINATOR[i];
    }
    for (i = 0; i < 3; i++) {
        mix_rate[i] = 0;
    }
    hal_coils(); /* st_coils[] all 0 after stepper_init() */
}

void robot_rx_isr(uint8_t byte)
{
    uint8_t bad = (uint8_t)(xp.bad_checksums + xp.truncated + xp.oversize + xp.busy);
    xp_feed(byte);
    if ((uint8_t)(xp.bad_checksums + xp.truncated + xp.oversize + xp.busy) != bad) {
        robot.faults |= SWP_FAULT_BAD_FRAME;
    }
}

void robot_uart_error(void)
{
    robot.faults |= SWP_FAULT_UART;
}

void robot_poll(void)
{
    uint16_t age;
    uint8_t faults;
    if (xp.ready && handle_frame()) {
        send_payload(SWP_LEN_ACK);
    }
    if (!robot.heartbeat_due) {
        return;
    }
    HAL_CRITICAL_BEGIN();
    robot.heartbeat_due = 0;
    age = robot.cmd_age_ms;
    faults = robot.faults;
    robot.faults &= SWP_FAULT_STICKY;
    /* unrolled: a variable index into 16-bit arrays costs the PIC14 a library multiply
     * and its RAM */
    robot.tx[5] = (uint8_t)((uint16_t)st_rate[0] >> 8);
    robot.tx[6] = (uint8_t)st_rate[0];
    robot.tx[7] = (uint8_t)((uint16_t)st_rate[1] >> 8);
    robot.tx[8] = (uint8_t)st_rate[1];
    robot.tx[9] = (uint8_t)((uint16_t)st_rate[2] >> 8);
    robot.tx[10] = (uint8_t)st_rate[2];
    HAL_CRITICAL_END();
    robot.tx[0] = SWP_MSG_STATUS;
    robot.tx[1] = robot.status_seq++;
    robot.tx[2] = robot.last_cmd_seq;
    robot.tx[3] = (uint8_t)(age >> 8);
    robot.tx[4] = (uint8_t)age;
    robot.tx[11] = faults;
    robot.tx[12] = (uint8_t)(xp.bad_checksums + xp.truncated + xp.oversize + xp.busy);
    robot.tx[13] = robot.foreign;
    send_payload(SWP_LEN_STATUS);
}

void robot_tick(void)
{
    uint8_t i;
    if (robot.cmd_age_ms != 0xFFFF) {
        robot.cmd_age_ms++;
    }
    if (robot.running && robot.cmd_age_ms >= SWP_CMD_TIMEOUT_MS) {
        for (i = 0; i < 3; i++) {
            st_rate[i] = 0;
        }
        robot.running = 0;
        robot.faults |= SWP_FAULT_WATCHDOG;
    }
    if (++robot.heartbeat_ms >= SWP_HEARTBEAT_MS) {
        robot.heartbeat_ms = 0;
        robot.heartbeat_due = 1;
    }
    stepper_tick();
    hal_coils();
}
