/* hal_pic16f690.c - the thin PIC16F690 layer: clocks, EUSART, Timer2, pins, main loop.
 *
 * Internal oscillator 8 MHz (2 MIPS). EUSART 9600 baud 8N1 on RB5 (RX) / RB7 (TX),
 * interrupt-driven receive: the interrupt parses each byte (robot_rx_isr) into a one-frame
 * mailbox that the main loop empties (robot_poll), so no receive ring is needed and a
 * main loop blocked sending a status loses no bytes. Timer2 interrupts at SWP_TICK_HZ
 * (8 MHz / 4 / prescale 4 / (PR2 + 1 = 125) / postscale 4 = 1 kHz) and runs robot_tick().
 * ULN2003 inputs: motor A on RC0-RC3, motor B on RC4-RC7, motor C on RA0 RA1 RA2 RA4.
 * The hardware watchdog (about 2.1 s) resets the chip if the main loop hangs.
 *
 * Registers are declared here by address (PIC16F690 data sheet DS41262, table 2-1), so
 * the build does not need the device headers that Debian's sdcc leaves out.
 */
#include <stdint.h>

#include "hal.h"
#include "robot.h"
#include "stepper.h"

/* Core registers, exported: the sdcc runtime (libsdcc) links against these names. */
__sfr __at(0x0000) INDF;
__sfr __at(0x0002) PCL;
__sfr __at(0x0003) STATUS;
__sfr __at(0x0004) FSR;
__sfr __at(0x000A) PCLATH;
/* Bank 0 */
static __sfr __at(0x0005) PORTA;
static __sfr __at(0x0007) PORTC;
static __sfr __at(0x000B) INTCON;
static __sfr __at(0x000C) PIR1;
static __sfr __at(0x0012) T2CON;
static __sfr __at(0x0018) RCSTA;
static __sfr __at(0x0019) TXREG;
static __sfr __at(0x001A) RCREG;
/* Bank 1 */
static __sfr __at(0x0085) TRISA;
static __sfr __at(0x0086) TRISB;
static __sfr __at(0x0087) TRISC;
static __sfr __at(0x008C) PIE1;
static __sfr __at(0x008F) OSCCON;
static __sfr __at(0x0092) PR2;
static __sfr __at(0x0098) TXSTA;
static __sfr __at(0x0099) SPBRG;
static __sfr __at(0x009A) SPBRGH;
static __sfr __at(0x009B) BAUDCTL;
/* Bank 2 */
static __sfr __at(0x011E) ANSEL;
static __sfr __at(0x011F) ANSELH;

/* Configuration word: INTOSCIO, WDT on, power-up timer on, MCLR on, no code protection,
 * brown-out reset on, no two-speed start-up, no fail-safe clock monitor. */
static __code uint16_t __at(0x2007) config_word = 0x33EC;

#define GIE 0x80
#define PEIE 0x40
#define RCIF 0x20
#define TXIF 0x10
#define TMR2IF 0x02
#define OERR 0x02
#define FERR 0x04
#define CREN 0x10

void hal_irq_off(void)
{
    INTCON &= (uint8_t)~GIE;
}

void hal_irq_on(void)
{
    INTCON |= GIE;
}

void hal_uart_put(uint8_t byte)
{
    while (!(PIR1 & TXIF)) {
    }
    TXREG = byte;
}

/* Whole-port writes, no read-modify-write: RA3 is an input, RA5 and RB unused. */
void hal_coils(void)
{
    PORTC = st_coils[0] | (uint8_t)(st_coils[1] << 4);
    PORTA = (st_coils[2] & 0x07) | (uint8_t)((st_coils[2] & 0x08) << 1);
}

static void isr(void) __interrupt 0
{
    if (PIR1 & RCIF) {
        if (RCSTA & (OERR | FERR)) {
            robot_uart_error();
            if (RCSTA & OERR) {
                RCSTA &= (uint8_t)~CREN; /* clearing CREN clears the overrun */
                RCSTA |= CREN;
            }
        }
        robot_rx_isr(RCREG);
    }
    if (PIR1 & TMR2IF) {
        PIR1 &= (uint8_t)~TMR2IF;
        robot_tick();
    }
}

void main(void)
{
    OSCCON = 0x71;            /* IRCF = 111: 8 MHz, internal clock */
    ANSEL = 0;                /* all pins digital */
    ANSELH = 0;
    PORTA = 0;
    PORTC = 0;
    TRISA = 0x08;             /* RA3 (MCLR) input, the rest outputs */
    TRISB = 0xA0;             /* RB5 RX, RB7 TX (EUSART drives them) */
    TRISC = 0x00;
    BAUDCTL = 0x08;           /* BRG16 */
    SPBRGH = 0;
    SPBRG = 207;              /* 8 MHz / (4 * (207 + 1)) = 9615 baud, +0.16 % */
    TXSTA = 0x24;             /* TXEN, BRGH, asynchronous */
    RCSTA = 0x90;             /* SPEN, CREN */
    PR2 = 124;
    T2CON = 0x1D;             /* postscale 1:4, on, prescale 1:4 */
    robot_init();
    PIE1 = RCIF | TMR2IF;     /* RCIE, TMR2IE */
    INTCON = GIE | PEIE;
    for (;;) {
        __asm
            clrwdt
        __endasm;
        robot_poll();
    }
}
