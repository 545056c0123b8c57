/* The quadrature decoding of the AVR binary under load: the four encoders turn at the rates of
 * 1 m/s (free wheels 12 732 counts/s, motors 4 760 counts/s), forward then turning on the spot,
 * while the control tick runs (it is preempted by the edges) and a master polls at 100 kHz. At
 * every tick, once no interrupt is pending, the binary's counters equal the edges delivered (each
 * counter's low byte overflows into its high byte 4 to 12 times each way), and no edge waited
 * for its interrupt longer than the interrupts that do not nest take. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

#include <cmocka.h>

#include "avrsim.h"
#include "robot.h"

static const char *elf_path;

static uint16_t u16(const struct avrsim *h, uint16_t addr)
{
	uint8_t b[2];

	avrsim_peek(h, addr, b, 2);
	return (uint16_t)(b[0] | b[1] << 8);
}

static void run_phase(struct avrsim *h, const double rate[4], uint32_t ticks, uint64_t *checks)
{
	uint16_t free_at, motor_at;
	uint8_t s;

	assert_int_equal(avrsim_symbol(h, "avr_free_count", &free_at), 0);
	assert_int_equal(avrsim_symbol(h, "avr_motor_count", &motor_at), 0);
	assert_int_equal(avrsim_encoders_turn(h, rate), 0);
	for (uint32_t t = 0; t < ticks; t++) {
		assert_int_equal(avrsim_run_to_tick_end(h), 0);
		if (t % 10 == 0)
			assert_int_equal(avrsim_i2c_read(h, &s, 1), 0);
		for (int i = 0; i < 1000 && !avrsim_interrupts_idle(h); i++)
			assert_int_equal(avrsim_run_cycles(h, 1), 0);
		assert_true(avrsim_interrupts_idle(h));
		for (int e = 0; e < 4; e++) {
			uint16_t got =
				u16(h, (uint16_t)((e < 2 ? free_at : motor_at) + 2 * (e & 1))) ^
				AVR_COUNT_BIAS;
			uint16_t want = (uint16_t)(uint64_t)avrsim_encoder_edges(h, e);

			if (got != want)
				fail_msg("tick %u: encoder %d counted %u, the pins moved to %u", t,
					 e, got, want);
		}
		(*checks)++;
	}
}

static void test_every_edge_counted(void **state)
{
	const double forward[4] = {12732.4, 12732.4, 4760.0, 4760.0};
	const double turning[4] = {-12732.4, 12732.4, -4760.0, 4760.0};
	struct avrsim *h = avrsim_open(elf_path, 100000);
	const struct avrsim_stats *st;
	struct board_config bc;
	uint64_t checks = 0;

	(void)state;
	assert_non_null(h);
	avr_robot_config(&bc);
	assert_int_equal(avrsim_run_to_tick_end(h), 0);
	run_phase(h, forward, bc.tick_hz / 4u, &checks);
	run_phase(h, turning, bc.tick_hz / 4u, &checks);
	st = avrsim_stats(h);
	print_message(
		"%llu edges over %.2f s, counters checked at %llu ticks; tick %.0f cycles mean, "
		"%llu worst\n",
		(unsigned long long)st->edges, (double)st->cycles / AVRSIM_F_CPU,
		(unsigned long long)checks, (double)st->tick.cycles / (double)st->tick.n,
		(unsigned long long)st->tick.max);
	print_message("an edge waited for its interrupt %.0f cycles mean, %llu at most\n",
		      (double)st->edge_wait.cycles / (double)st->edge_wait.n,
		      (unsigned long long)st->edge_wait.max);
	/* No edge waits for a tick, only for the interrupts that do not nest (the TWI's is the
	 * longest, about 400 cycles): far less than the 1 256 cycles between two edges of a free
	 * wheel's channel at 1 m/s. */
	assert_true(st->edge_wait.max < 1000u);
	avrsim_close(h);
}

int main(int argc, char **argv)
{
	const struct CMUnitTest tests[] = {
		cmocka_unit_test(test_every_edge_counted),
	};

	if (argc != 2) {
		fprintf(stderr, "usage: %s asserv_avr.elf\n", argv[0]);
		return 2;
	}
	elf_path = argv[1];
	return cmocka_run_group_tests(tests, NULL, NULL);
}
