/* hal_host.c - host (gcc) implementation of hal.h plus a ctypes-friendly harness.
 *
 * Built into build/host/libswarmfw.so by `make host`; tests/unit/bridge loads it with
 * ctypes, feeds it frames from the Python encoder and reads what the board would send.
 */
#include <stdint.h>

#include "hal.h"
#include "robot.h"
#include "stepper.h"

#define HOST_TX_CAPACITY 8192

uint8_t host_tx[HOST_TX_CAPACITY];
uint32_t host_tx_len;
uint32_t host_tx_dropped;
uint8_t host_coils[3];

void hal_uart_put(uint8_t byte)
{
    if (host_tx_len < HOST_TX_CAPACITY) {
        host_tx[host_tx_len++] = byte;
    } else {
        host_tx_dropped++;
    }
}

void hal_coils(void)
{
    uint8_t ch;
    for (ch = 0; ch < 3; ch++) {
        host_coils[ch] = st_coils[ch];
    }
}

/* Reset the board as at power-up. */
void fw_reset(void)
{
    host_tx_len = 0;
    host_tx_dropped = 0;
    robot_init();
}

/* Feed n received bytes, each through the receive interrupt followed by a main-loop
 * pass (which empties the mailbox as soon as a frame is complete). */
void fw_feed(const uint8_t *data, uint32_t n)
{
    uint32_t i;
    for (i = 0; i < n; i++) {
        robot_rx_isr(data[i]);
        robot_poll();
    }
}

/* Feed n bytes through the receive interrupt only: a main loop that is busy elsewhere. */
void fw_feed_isr(const uint8_t *data, uint32_t n)
{
    uint32_t i;
    for (i = 0; i < n; i++) {
        robot_rx_isr(data[i]);
    }
}

/* Run n timer ticks (1 ms each), polling the main loop after each one. */
void fw_ticks(uint32_t n)
{
    uint32_t i;
    for (i = 0; i < n; i++) {
        robot_tick();
        robot_poll();
    }
}

/* Forget the bytes sent so far. */
void fw_clear_tx(void)
{
    host_tx_len = 0;
}
