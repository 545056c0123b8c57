/* Template port: the start of a new port. It compiles and links with the core and the common
 * port layer (its build: firmware/CMakeLists.txt, target asserv_template), and every function of
 * the porting contract (firmware/hal/) is a stub that says what it must do, one file per header:
 * encoder.c, motor.c, sensors.c, i2c.c, tick.c, nvm.c (hal_nvm.h is implemented for byte storage
 * by ports/common/nvm_bytes.c: nvm.c stubs its four byte functions, and says when a port writes
 * its own instead). The rest has the finished ports' file names: robot.c (the configuration),
 * reset.c (why the chip started), watchdog.c, and this main.c (the start-up's order). To start
 * a port: copy this folder to ports/<name>, rename the template_ prefix, fill in each stub from
 * the chip's reference manual, attach template_tick_isr() and template_i2c_event() to the chip's
 * interrupts, and describe the robot in robot/<name>.toml. ports/avr and ports/stm32 are two
 * finished examples. */
#include <stddef.h>

#include "hal.h"
#include "nvm_bytes.h"
#include "port.h"
#include "protocol_defs.h"
#include "template_port.h"

/* A real port puts it in RAM its start-up does not clear (the AVR's and the STM32's .noinit
 * section), so that board_restart() finds in it what a reset keeps (keep.h). */
struct board asserv_board;

/* The calibration's records in the storage (hal_nvm.h): loaded at start, written by the main
 * loop. Its type is the implementation's: nvm_bytes.h's here (byte storage, nvm.c); a flash
 * port's own, as stm32_nvm.h's. */
static struct hal_nvm template_nvm;

int main(void)
{
	struct board_config cfg;
	struct board_inputs in;
	uint8_t cause = template_reset_cause(); /* first, before anything clears the flags */

	/* Clocks, pins, timers, ADC: the chip's own start-up, with the motors off. */
	template_robot_config(&cfg);
	/* The counts the odometry starts from, so that the first tick sees no jump. */
	port_sample(&in);
	port_sample_period(&in);
	/* board_init(), then after any reset but a power-on the pose a reset kept resumes. */
	if (board_restart(&asserv_board, &cfg, &in, cause, template_down_ms(cause)) != 0) {
		/* A configuration the core refuses: motors off, no bus, wait for a new binary. */
		for (;;)
			;
	}
	/* After board_restart(), before the bus and the ticks: the calibration the storage keeps,
	 * installed. A blank or corrupt record leaves the board uncalibrated: it runs all the same.
	 * nvm_bytes_init() names the storage (NULL: the one chip nvm.c drives); a flash port with
	 * its own hal_nvm has no such call. */
	nvm_bytes_init(&template_nvm, NULL);
	hal_nvm_load(&template_nvm, &asserv_board);
	hal_i2c_slave_init(PROTO_ADDRESS);
	template_watchdog_start();
	hal_tick_start(cfg.tick_hz);
	/* enable interrupts here */
	for (;;) {
		/* A port with two rates runs port_slow(&asserv_board) here first (tick.c). Then the
		 * calibration's record: what the storage takes without waiting (one byte write at
		 * most on an EEPROM), never from the control interrupt. Then sleep until an
		 * interrupt. */
		hal_nvm_poll(&template_nvm, &asserv_board);
	}
}
