/* hal.h - the thin hardware layer the portable firmware calls.
 * hal_pic16f690.c implements it on the chip, host/hal_host.c for the host tests. */
#ifndef HAL_H
#define HAL_H

#include <stdint.h>

/* Send one byte on the EUSART (blocking until the transmit register is free). */
void hal_uart_put(uint8_t byte);
/* Drive the ULN2003 inputs of the three stepper channels (A, B, C) with st_coils[]
 * (stepper.h). Called from the timer interrupt, so it takes no arguments: on the PIC every
 * argument or result byte after the first travels in sdcc's STK00.. registers, which the
 * interrupt does not save (PROTOCOL.md, "Interrupt rule"). */
void hal_coils(void);

#if defined(__SDCC)
/* Mask / unmask interrupts around state shared with the timer interrupt. */
void hal_irq_off(void);
void hal_irq_on(void);
#define HAL_CRITICAL_BEGIN() hal_irq_off()
#define HAL_CRITICAL_END() hal_irq_on()
#else
#define HAL_CRITICAL_BEGIN() do { } while (0)
#define HAL_CRITICAL_END() do { } while (0)
#endif

#endif
