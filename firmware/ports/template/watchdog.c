/* Template port: the watchdog, as ports/stm32/watchdog.c and ports/avr/watchdog.c. Its reset is
 * what stops the motors when the ticks stop: the PWM pins then float, so the bridge's enable
 * inputs need pull-downs. */
#include "template_port.h"

/* Start it with a window of a few control periods (60 ms on the AVR and the STM32), from main()
 * once the board is initialised and before the ticks start. A chip whose flash stalls the CPU
 * while it erases widens the window around the erase (the STM32's nvm.c). */
void template_watchdog_start(void)
{
}

/* Feed it: from the control interrupt after each tick (the STM32), or from the main loop only
 * when the servo has run since the last feed (the AVR with two rates), so that a stuck main loop
 * and a stopped tick both let it reset the chip. Never from a timer of its own that would
 * outlive a stopped tick. */
void template_watchdog_feed(void)
{
}
