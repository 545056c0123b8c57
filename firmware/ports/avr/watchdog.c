/* The watchdog (the datasheet's "Watchdog Timer", avr-libc's <avr/wdt.h>), as
 * ports/stm32/watchdog.c: started by main() with avr-libc's 60 ms window (8K cycles of the
 * 128 kHz watchdog oscillator, which drifts with the supply and the temperature), fed by the main
 * loop after each tick (one rate) or after the slow steps when the servo has run since (two
 * rates, main.c), so that if the ticks stop or the main loop hangs it resets the chip, and the
 * reset stops the motors (the pins go to inputs: the bridge's enable inputs need pull-downs). */
#include <avr/wdt.h>

#include "avr_port.h"

/* A watchdog reset leaves the watchdog on, at its shortest window: off before the start-up's
 * loops (main.c's .init3 code, after it has saved MCUSR: WDRF cleared first, or WDE stays set). */
void avr_watchdog_off(void)
{
	wdt_disable();
}

/* The 60 ms window, from main() once the board is initialised and before the ticks' interrupt
 * is enabled. */
void avr_watchdog_start(void)
{
	wdt_enable(WDTO_60MS);
}

/* Feed it (wdr): from the main loop only (main.c says when), never from a timer of its own that
 * would outlive a stopped tick. */
void avr_watchdog_feed(void)
{
	wdt_reset();
}
