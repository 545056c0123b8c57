/* The asserv board on an ATmega1284P at 16 MHz: start-up, then the main loop, which runs the
 * whole control tick (one rate) or the slow steps (two rates; tick.c explains both). Pin map:
 * pinmap.h; build, fuses and flashing: docs/avr.md. */
#include <stddef.h>

#include <avr/interrupt.h>
#include <avr/io.h>

#include "avr_port.h"
#include "hal.h"
#include "nvm_bytes.h"
#include "pinmap.h"
#include "port.h"

/* Not cleared by the start-up (avr-libc's .noinit): what a reset keeps (keep.h) is in it. */
struct board asserv_board __attribute__((section(".noinit")));

/* MCUSR as the reset left it, saved before the start-up (which would clear a .bss variable). */
static uint8_t avr_mcusr __attribute__((section(".noinit")));

/* The calibration's records in the EEPROM (hal_nvm.h over nvm.c's bytes): loaded at start,
 * written by the main loop. */
static struct hal_nvm avr_nvm;

/* Periods the tick missed because the previous one ran over (a debugger reads it): counted by
 * the main loop (one rate) or by the timer's interrupt (two rates, tick_isr.S). */
volatile uint16_t avr_tick_overruns;

/* After a watchdog reset the watchdog stays on: turn it off before anything else (WDRF must be
 * cleared first: watchdog.c), keeping the reset flags for main(). */
void avr_early_init(void) __attribute__((naked, used, section(".init3")));
void avr_early_init(void)
{
	avr_mcusr = MCUSR;
	MCUSR = 0;
	avr_watchdog_off();
}

int main(void)
{
	struct board_config cfg;
	struct board_inputs in;

	/* JTAG off so that PC2..PC5 are the free encoders' pins (two writes within 4 cycles). */
	MCUCR = _BV(JTD);
	MCUCR = _BV(JTD);
	avr_sensors_init();
	avr_motor_init();
	avr_encoder_init();
	avr_robot_config(&cfg);
	port_sample(&in);
	port_sample_period(&in);
	/* The down time is unused: this build refuses the pose after a reset (CONFIG_KEEP_POSE,
	 * CMakeLists.txt). */
	if (cfg.slow_shift != CONFIG_AVR_SLOW_SHIFT ||
	    board_restart(&asserv_board, &cfg, &in, avr_reset_cause(avr_mcusr), 0) != 0) {
		/* A configuration the core refuses, or rates the execution model built in does not
		 * run (tick.c): motors off, no bus, wait for a new binary. */
		for (;;)
			;
	}
	/* A blank or corrupt record leaves the board uncalibrated: it runs all the same. */
	nvm_bytes_init(&avr_nvm, NULL); /* the one EEPROM (nvm.c) */
	hal_nvm_load(&avr_nvm, &asserv_board);
	hal_i2c_slave_init(PROTO_ADDRESS);
	hal_tick_start(cfg.tick_hz);
	avr_watchdog_start(); /* 60 ms (watchdog.c) */
	sei();
#if CONFIG_AVR_SLOW_SHIFT == 0
	for (;;) {
		uint8_t n = avr_tick_wait();

		if (n > 1)
			avr_tick_overruns += (uint16_t)(n - 1u);
		PORTD |= _BV(PIN_TICK_BIT);
		avr_motor_sense();
		port_control_tick(&asserv_board);
		PORTD &= (uint8_t)~_BV(PIN_TICK_BIT);
		hal_nvm_poll(&avr_nvm, &asserv_board); /* a byte at most, never waited for */
		avr_watchdog_feed();
	}
#else
	for (;;) {
		avr_slow_wait();
		PORTD |= _BV(PIN_SLOW_BIT);
		port_slow(&asserv_board);
		PORTD &= (uint8_t)~_BV(PIN_SLOW_BIT);
		hal_nvm_poll(&avr_nvm, &asserv_board); /* a byte at most, never waited for */
		/* Fed only here, and only if the servo has run since: a main loop stuck in the slow
		 * steps, and a servo that stopped (the slow steps then never fall due), both let
		 * the watchdog stop the motors. */
		if (avr_servo_alive) {
			avr_servo_alive = 0;
			avr_watchdog_feed();
		}
	}
#endif
}
