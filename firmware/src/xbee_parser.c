/* xbee_parser.c - streaming XBee API mode 2 frame parser.
 *
 * A raw 0x7E always starts a new frame (in mode 2 it cannot occur inside one), so the
 * parser resynchronises on garbage, truncated frames and bad checksums by itself. A raw
 * XON/XOFF inside a frame, or an escape of an ordinary byte, is a corrupted escape
 * sequence: the frame is dropped and counted with the garbage (no RAM for a counter).
 * Runs in the receive interrupt (hal_pic16f690.c); see xbee_parser.h for the mailbox.
 */
#include "xbee_parser.h"

#define XP_WAIT_START 0
#define XP_LEN_HI     1
#define XP_LEN_LO     2
#define XP_DATA       3
#define XP_CHECKSUM   4

xbee_parser_t xp;

void xp_reset(void)
{
    uint8_t i;
    uint8_t *p = (uint8_t *)&xp;
    for (i = 0; i < sizeof(xp); i++) {
        p[i] = 0;
    }
}

uint8_t xp_feed(uint8_t byte)
{
    if (byte == SWP_XBEE_START) {
        if (xp.state != XP_WAIT_START) {
            xp.truncated++;
        }
        xp.state = XP_LEN_HI;
        xp.escaped = 0;
        return 0;
    }
    if (xp.state == XP_WAIT_START) {
        xp.garbage++;
        return 0;
    }
    if (byte == SWP_XBEE_ESCAPE) {
        xp.escaped = 1;
        return 0;
    }
    if (xp.escaped) {
        byte ^= SWP_XBEE_ESCAPE_XOR;
        xp.escaped = 0;
        if (byte != SWP_XBEE_START && byte != SWP_XBEE_ESCAPE && byte != SWP_XBEE_XON
            && byte != SWP_XBEE_XOFF) {
            xp.garbage++;            /* only the four special bytes are ever escaped */
            xp.state = XP_WAIT_START;
            return 0;
        }
    } else if (byte == SWP_XBEE_XON || byte == SWP_XBEE_XOFF) {
        xp.garbage++;                /* never raw inside a mode 2 frame: corrupted   */
        xp.state = XP_WAIT_START;
        return 0;
    }
    switch (xp.state) {
    case XP_LEN_HI:
        if (byte != 0) {
            xp.oversize++;
            xp.state = XP_WAIT_START;
        } else {
            xp.state = XP_LEN_LO;
        }
        break;
    case XP_LEN_LO:
        if (byte == 0 || byte > SWP_MAX_FRAME_DATA) {
            xp.oversize++;
            xp.state = XP_WAIT_START;
        } else if (xp.ready) {
            xp.busy++;               /* the main loop has not taken the last frame */
            xp.state = XP_WAIT_START;
        } else {
            xp.length = byte;
            xp.index = 0;
            xp.sum = 0;
            xp.state = XP_DATA;
        }
        break;
    case XP_DATA:
        if (xp.index < XP_KEEP_HEAD) {
            xp.buf[xp.index] = byte;
        } else if (xp.index >= SWP_RX_HEADER_LEN) {
            /* unsigned index: sdcc's pic14 port mishandles a signed (int) index into an
             * array above 0x80 (it sets IRP from the sum's bit 7; gpsim caught it) */
            xp.buf[(uint8_t)(xp.index - (SWP_RX_HEADER_LEN - XP_KEEP_HEAD))] = byte;
        }
        xp.index++;
        xp.sum += byte;
        if (xp.index == xp.length) {
            xp.state = XP_CHECKSUM;
        }
        break;
    default: /* XP_CHECKSUM */
        xp.state = XP_WAIT_START;
        if ((uint8_t)(xp.sum + byte) == SWP_XBEE_CHECKSUM_OK) {
            xp.frames++;
            xp.ready = 1;
            return 1;
        }
        xp.bad_checksums++;
        break;
    }
    return 0;
}
