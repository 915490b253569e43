/* ATmega328P (Arduino Uno/Nano, 16 MHz) board layer: encoders, clock, UART, DAC, relay. */
#ifndef AC_BOARD_H
#define AC_BOARD_H

#ifdef __cplusplus
extern "C" {
#endif

void ac_app_setup(void);    /* everything up, outputs neutral, interrupts on */
void ac_app_loop_once(void); /* one pass of the main loop; sleeps (idle) when there is nothing to do */

#ifdef __cplusplus
}
#endif
#endif
