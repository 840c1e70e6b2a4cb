/* hal.h - the thin hardware layer the portable firmware calls.
 * hal_pic16f690.c implements it on the chip, host/hal_host.c for the host tests. */
#ifndef HAL_H
#define HAL_H

#include <stdint.h>

/* Send one byte on the EUSART (blocking until the transmit register is free). */
void hal_uart_put(uint8_t byte);
/* Drive the four ULN2003 inputs of stepper channel ch (0 = A, 1 = B, 2 = C). */
void hal_coils(uint8_t ch, uint8_t pattern);

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
