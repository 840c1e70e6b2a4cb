/* xbee_parser.h - streaming XBee API mode 2 frame parser (hardware independent). */
#ifndef XBEE_PARSER_H
#define XBEE_PARSER_H

#include <stdint.h>

#include "swarm_protocol.h"

/* Bytes kept of a frame: frame data 0..8 (API type, 64-bit source address) and the RF
 * data from offset SWP_RX_HEADER_LEN on; the 16-bit address and options are skipped. */
#define XP_KEEP_HEAD  9
#define XP_BUF_LEN    (XP_KEEP_HEAD + SWP_MAX_MSG_IN)
#define XP_MSG        XP_KEEP_HEAD   /* index of the RF data (message) in buf          */

/* The one parser instance of the board (a global: cheap to address on the PIC14).
 * It runs in the receive interrupt; buf doubles as the mailbox to the main loop: a
 * finished, checksum-valid frame sets ready, and frames that start while ready is set
 * are dropped and counted as busy. The main loop copies what it needs and clears ready.
 * Counters first: their offsets do not move when the buffer size changes.          */
typedef struct {
    uint8_t frames;       /* counters, modulo 256                                  */
    uint8_t bad_checksums;
    uint8_t truncated;    /* a start delimiter arrived inside a frame             */
    uint8_t oversize;     /* announced length 0 or above SWP_MAX_FRAME_DATA       */
    uint8_t garbage;      /* bytes outside any frame, and corrupted escapes       */
    uint8_t busy;         /* frames dropped: the mailbox still held the previous  */
    uint8_t state;        /* XP_* below                                          */
    uint8_t escaped;      /* previous byte was SWP_XBEE_ESCAPE                    */
    uint8_t length;       /* announced frame data length                          */
    uint8_t index;        /* frame data bytes received so far                     */
    uint8_t sum;          /* running sum of the frame data                        */
    volatile uint8_t ready; /* mailbox full: buf holds a frame of length bytes    */
    uint8_t buf[XP_BUF_LEN];
} xbee_parser_t;

extern xbee_parser_t xp;

void xp_reset(void);
/* Feed one received byte (receive interrupt); returns 1 when a complete,
 * checksum-valid frame of xp.length bytes is in the mailbox (xp.ready set). */
uint8_t xp_feed(uint8_t byte);

#endif
