/* robot.h - the board's application: commands, watchdog, heartbeats (hardware independent).
 *
 * Contexts: robot_tick() runs in the timer interrupt, robot_rx_isr() in the receive
 * interrupt (it parses frames into the parser's one-frame mailbox, xbee_parser.h);
 * robot_init() and robot_poll() run in the main loop, which changes state shared with
 * the interrupts only under HAL_CRITICAL.
 */
#ifndef ROBOT_H
#define ROBOT_H

#include <stdint.h>

#include "swarm_protocol.h"

typedef struct {
    uint16_t cmd_age_ms;     /* since the last valid command (saturates)           */
    uint16_t heartbeat_ms;   /* since the last status                                */
    uint8_t heartbeat_due;   /* set by robot_tick, cleared by robot_poll             */
    uint8_t faults;          /* SWP_FAULT_* flags                                    */
    uint8_t status_seq;
    uint8_t last_cmd_seq;
    uint8_t running;         /* a nonzero wheel rate is applied                      */
    uint8_t foreign;         /* 0x90 frames dropped: not from the coordinator (mod 256) */
    uint8_t host[8];         /* the coordinator's 64-bit address (SWP_COORDINATOR_ADDR64):
                              * the only sender obeyed, where statuses and acks go   */
    uint8_t tx[SWP_LEN_STATUS];
} robot_t;

extern robot_t robot;

void robot_init(void);
/* Receive interrupt: one UART byte into the frame parser (no sending, no mixing). */
void robot_rx_isr(uint8_t byte);
/* Main loop: handle the frame in the mailbox (mix, answer), send the heartbeat when due. */
void robot_poll(void);
/* Timer interrupt, SWP_TICK_HZ: command watchdog, heartbeat timer, step timing, coils. */
void robot_tick(void);
/* Interrupt or main loop: the EUSART reported an overrun or framing error. */
void robot_uart_error(void);

#endif
