/* The AVR binary's sensor inputs, through its pins and its ADC, without physics: each shock
 * switch alone in INFO_CHOC's reply (the pin map puts CAPTEUR_2 and CAPTEUR_3 on port A, the
 * others on port B), and the motor currents in DEBUG's once the filter has settled, each
 * channel with its own sign and magnitude (the tick converts the channels in turn and samples
 * the currents only at a period's end). */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>

#include "avrsim.h"
#include "protocol.h"

static const char *elf_path;

static void run_ticks(struct avrsim *h, unsigned n)
{
	for (unsigned t = 0; t < n; t++)
		assert_int_equal(avrsim_run_to_tick_end(h), 0);
}

static void query(struct avrsim *h, uint8_t designation, uint8_t *reply, uint8_t n)
{
	assert_int_equal(avrsim_i2c_write(h, &designation, 1, 0), 0);
	assert_int_equal(avrsim_i2c_read(h, reply, n), 0);
}

static void test_each_shock_switch(void **state)
{
	struct avrsim *h = avrsim_open(elf_path, 100000);
	struct sim_sensors s;
	uint8_t got;

	(void)state;
	assert_non_null(h);
	memset(&s, 0, sizeof(s));
	run_ticks(h, 20);
	query(h, PROTO_INFO_CHOC, &got, 1);
	assert_int_equal(got, 0);
	for (int i = 0; i < 8; i++) {
		s.shock_mask = (uint8_t)(1u << i);
		assert_int_equal(avrsim_sensors_set(h, &s), 0);
		/* A change shows in the replies published at the hand-over after the slow steps of
		 * the first period that ends with it: under 3 periods of 8 ticks. */
		run_ticks(h, 24);
		query(h, PROTO_INFO_CHOC, &got, 1);
		if (got != s.shock_mask)
			fail_msg("CAPTEUR_%d pressed: INFO_CHOC says 0x%02x", i, got);
	}
	avrsim_close(h);
}

static int16_t be16(const uint8_t *b)
{
	return (int16_t)((uint16_t)b[0] << 8 | b[1]);
}

static void test_motor_currents(void **state)
{
	/* left, right [mA]; an ADC step is 5000 mV / 1024 / (100 mV/A) = 48.8 mA */
	static const int32_t cases[][2] = {{1500, -700}, {-3000, 250}, {0, 0}};
	struct avrsim *h = avrsim_open(elf_path, 100000);
	struct sim_sensors s;
	uint8_t d[PROTO_DEBUG_REPLY_LEN];

	(void)state;
	assert_non_null(h);
	memset(&s, 0, sizeof(s));
	run_ticks(h, 4);
	for (size_t c = 0; c < sizeof(cases) / sizeof(cases[0]); c++) {
		s.current_mA[0] = cases[c][0];
		s.current_mA[1] = cases[c][1];
		assert_int_equal(avrsim_sensors_set(h, &s), 0);
		/* a channel's reading every other tick, the filter's time constant 4 readings */
		run_ticks(h, 120);
		query(h, PROTO_DEBUG, d, sizeof(d));
		for (int ch = 0; ch < 2; ch++) {
			int16_t ma = be16(&d[16 + 2 * ch]); /* current_left_ma, current_right_ma */

			/* within 1.5 ADC steps: the ADC's floor (1 step), and simavr's scale
			 * (readings of mV * 1023 / 5000 where the AVR's are mV * 1024 / 5000) */
			if (abs(ma - cases[c][ch]) > 73)
				fail_msg("%s motor at %d mA: DEBUG says %d mA",
					 ch ? "right" : "left", (int)cases[c][ch], (int)ma);
		}
	}
	avrsim_close(h);
}

int main(int argc, char **argv)
{
	const struct CMUnitTest tests[] = {
		cmocka_unit_test(test_each_shock_switch),
		cmocka_unit_test(test_motor_currents),
	};

	if (argc != 2) {
		fprintf(stderr, "usage: %s asserv_avr.elf\n", argv[0]);
		return 2;
	}
	elf_path = argv[1];
	return cmocka_run_group_tests(tests, NULL, NULL);
}
