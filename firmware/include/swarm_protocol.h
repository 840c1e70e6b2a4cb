/*
 * swarm_protocol.h - the one definition of the robot link (see PROTOCOL.md).
 *
 * Shared by the PIC16F690 firmware and, through a unit test that parses this file,
 * by the Python bridge (swarm_bridge/protocol.py must carry identical values).
 * Plain #defines only: no code, no floating point.
 *
 * Byte order of every multi-byte field: big-endian (as XBee API frames).
 */
#ifndef SWARM_PROTOCOL_H
#define SWARM_PROTOCOL_H

/* ---- XBee API mode 2 framing (AP=2) ------------------------------------------------ */
#define SWP_XBEE_START            0x7E  /* start delimiter, never escaped              */
#define SWP_XBEE_ESCAPE           0x7D  /* escape marker: next byte is XORed with 0x20 */
#define SWP_XBEE_XON              0x11  /* escaped in API mode 2                        */
#define SWP_XBEE_XOFF             0x13  /* escaped in API mode 2                        */
#define SWP_XBEE_ESCAPE_XOR       0x20
#define SWP_XBEE_CHECKSUM_OK      0xFF  /* sum of frame data + checksum, modulo 256     */

/* API frame types (frame data byte 0) */
#define SWP_API_TX_REQUEST        0x10  /* host -> radio: transmit to a 64-bit address  */
#define SWP_API_TX_STATUS         0x8B  /* radio -> host: delivery report of a 0x10     */
#define SWP_API_RX_PACKET         0x90  /* radio -> host: received RF data              */

/* Layout of the frames we use (offsets into frame data) */
#define SWP_TX_HEADER_LEN         14    /* type, id, addr64[8], addr16[2], radius, opts */
#define SWP_RX_HEADER_LEN         12    /* type, addr64[8], addr16[2], options          */
#define SWP_TX_STATUS_LEN         7     /* type, id, addr16[2], retries, delivery, disc */
#define SWP_ADDR16_UNKNOWN        0xFFFE
#define SWP_DELIVERY_OK           0x00
#define SWP_DELIVERY_NO_ACK       0x21  /* network ACK failure: the board did not answer */
#define SWP_DELIVERY_NOT_FOUND    0x24  /* address not found                             */

/* Largest frame data the firmware accepts: a 0x90 header and the longest message it
 * receives (CMD_VEL); longer frames are dropped and counted as oversize. The parser
 * keeps only frame data bytes 0..8 (type, source address) and the message.          */
#define SWP_MAX_MSG_IN            6
#define SWP_MAX_FRAME_DATA        18    /* SWP_RX_HEADER_LEN + SWP_MAX_MSG_IN          */

/* ---- Robot messages (RF data of 0x10 / 0x90 frames) -------------------------------- */
/* byte 0: message type, byte 1: sequence number; lengths are exact.                   */
#define SWP_MSG_CMD_VEL           0x01  /* type seq speed[2] direction[2]               */
#define SWP_MSG_STOP              0x02  /* type seq                                     */
#define SWP_MSG_STATUS            0x81  /* type seq last_cmd_seq age[2] rate[3][2] faults bad_frames foreign */
#define SWP_MSG_ACK               0x82  /* type acked_seq acked_type result             */

#define SWP_LEN_CMD_VEL           6
#define SWP_LEN_STOP              2
#define SWP_LEN_STATUS            14
#define SWP_LEN_ACK               4

/* ACK result codes */
#define SWP_ACK_OK                0
#define SWP_ACK_BAD_LENGTH        1
#define SWP_ACK_UNKNOWN_TYPE      2
#define SWP_ACK_BAD_VALUE         3

/* Status fault flags */
#define SWP_FAULT_WATCHDOG        0x01  /* motors stopped: no valid command for SWP_CMD_TIMEOUT_MS */
#define SWP_FAULT_BAD_FRAME       0x02  /* bad checksum, truncated or oversize frame seen  */
#define SWP_FAULT_RATE_LIMIT      0x04  /* a wheel rate was clipped to SWP_MAX_STEP_RATE   */
#define SWP_FAULT_UART            0x08  /* EUSART overrun or framing error                  */
#define SWP_FAULT_BAD_MSG         0x10  /* unknown message type, bad length or bad value    */
#define SWP_FAULT_FOREIGN         0x20  /* a 0x90 frame from another address than the       */
                                        /* coordinator's was dropped (status byte foreign) */
#define SWP_FAULT_RESET           0x80  /* set from power-up until the first status is sent */
#define SWP_FAULT_STICKY          SWP_FAULT_WATCHDOG /* the others clear once reported      */

/* ---- Units and fixed point (eqs. 5.1-5.3) ------------------------------------------ */
/* speed: unsigned, 0.1 mm/s per unit;  direction alpha: degrees 0..359, clockwise from  */
/* the robot's forward axis (thesis ch. 5 convention).                                   */
#define SWP_SPEED_UNITS_PER_M_S   10000
#define SWP_DIRECTION_FULL_TURN   360
/* Wheel drive directions, degrees clockwise from forward: V_i = |Vel| cos(phi_i - alpha) */
#define SWP_WHEEL_PHI_A           150   /* eq. 5.1 */
#define SWP_WHEEL_PHI_B           30    /* eq. 5.2 */
#define SWP_WHEEL_PHI_C           270   /* eq. 5.3 */
/* Quarter-wave sine table, sin(d deg) * 2^15 rounded, d = 0..90 */
#define SWP_SIN_SHIFT             15
#define SWP_SIN_TABLE_LEN         91
#define SWP_SIN_Q15_TABLE { \
        0,   572,  1144,  1715,  2286,  2856,  3425,  3993,  4560,  5126, \
     5690,  6252,  6813,  7371,  7927,  8481,  9032,  9580, 10126, 10668, \
    11207, 11743, 12275, 12803, 13328, 13848, 14365, 14876, 15384, 15886, \
    16384, 16877, 17364, 17847, 18324, 18795, 19261, 19720, 20174, 20622, \
    21063, 21498, 21926, 22348, 22763, 23170, 23571, 23965, 24351, 24730, \
    25102, 25466, 25822, 26170, 26510, 26842, 27166, 27482, 27789, 28088, \
    28378, 28660, 28932, 29197, 29452, 29698, 29935, 30163, 30382, 30592, \
    30792, 30983, 31164, 31336, 31499, 31651, 31795, 31928, 32052, 32166, \
    32270, 32365, 32449, 32524, 32588, 32643, 32688, 32723, 32748, 32763, \
    32768 }

/* ---- Drive train (28BYJ-48 class geared stepper on a ULN2003, 58 mm omni wheel) ---- */
#define SWP_HALF_STEPS_PER_REV    4096
#define SWP_WHEEL_DIAMETER_UM     58000
/* half-steps per speed unit (0.1 mm), Q12: round(4096 / (pi * 58 mm) / 10 * 4096)      */
#define SWP_STEPS_PER_UNIT_Q12    9208
#define SWP_STEPS_SHIFT           12
#define SWP_MAX_STEP_RATE         800   /* half-steps per second, per wheel             */

/* ---- Timing ------------------------------------------------------------------------ */
#define SWP_TICK_HZ               1000  /* stepper / watchdog tick (timer interrupt)    */
#define SWP_CMD_TIMEOUT_MS        500   /* motors stop this long after the last command */
#define SWP_HEARTBEAT_MS          200   /* status period                                 */
#define SWP_BAUD                  9600

/* ---- Who may command the board ------------------------------------------------------ */
/* SWP_COORDINATOR_ADDR64, the 64-bit address (SH + SL) of the coordinator XBee, is in
 * swarm_coordinator.h, which the Makefile generates in the build directory from the fleet
 * file's `coordinator` (or COORDINATOR=16 hex digits; tools/coordinator_header.py). The
 * board obeys only 0x90 frames whose source address equals it, and sends its acks and
 * statuses to it; other 0x90 frames are dropped unanswered and counted (status byte
 * foreign, fault SWP_FAULT_FOREIGN). */

#endif /* SWARM_PROTOCOL_H */
