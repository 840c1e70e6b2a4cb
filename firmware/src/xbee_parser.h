/* xbee_parser.h - streaming XBee API mode 2 frame parser (hardware independent). */
#ifndef XBEE_PARSER_H
#define XBEE_PARSER_H

#include <stdint.h>

#include "swarm_protocol.h"

/* The one parser instance of the board (a global: cheap to address on the PIC14). */
typedef struct {
    uint8_t state;        /* XP_* below                                          */
    uint8_t escaped;      /* previous byte was SWP_XBEE_ESCAPE                    */
    uint8_t length;       /* announced frame data length                          */
    uint8_t index;        /* frame data bytes received so far                     */
    uint8_t sum;          /* running sum of the frame data                        */
    uint8_t buf[SWP_MAX_FRAME_DATA];
    uint8_t frames;       /* counters, modulo 256                                  */
    uint8_t bad_checksums;
    uint8_t truncated;    /* a start delimiter arrived inside a frame             */
    uint8_t oversize;     /* announced length 0 or above SWP_MAX_FRAME_DATA       */
    uint8_t garbage;      /* bytes outside any frame                              */
} xbee_parser_t;

extern xbee_parser_t xp;

void xp_reset(void);
/* Feed one received byte; returns 1 when xp.buf holds a complete, checksum-valid frame
 * of xp.length bytes (valid until the next call). */
uint8_t xp_feed(uint8_t byte);

#endif
