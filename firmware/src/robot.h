/* robot.h - the board's application: commands, watchdog, heartbeats (hardware independent).
 *
 * Contexts: robot_tick() runs in the timer interrupt; every other function runs in the
 * main loop. State shared by both is only changed by the main loop under HAL_CRITICAL.
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
    uint8_t host[8];         /* 64-bit address statuses and acks go to               */
    uint8_t tx[SWP_LEN_STATUS];
} robot_t;

extern robot_t robot;

void robot_init(void);
/* Main loop: one received UART byte (parses, handles complete frames, answers). */
void robot_rx_byte(uint8_t byte);
/* Main loop: send the heartbeat when due. */
void robot_poll(void);
/* Timer interrupt, SWP_TICK_HZ: command watchdog, heartbeat timer, step timing, coils. */
void robot_tick(void);
/* Interrupt or main loop: the EUSART reported an overrun or framing error. */
void robot_uart_error(void);

#endif
