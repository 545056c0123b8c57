/* Benchmark of the physics simulator: prints substeps per second and the real-time factor, on
 * an open floor and while pushing against a border (contacts active). Not a test. */
#include <stdio.h>
#include <time.h>

#include "sim.h"

static double run(const char *name, bool wall, double sim_seconds)
{
	struct sim_config cfg;
	struct sim_field field;
	struct sim_sensors sens;
	struct sim s;
	long tick, ticks = (long)(sim_seconds * 1000.0);
	unsigned checksum = 0;
	clock_t t0, t1;
	double cpu, steps;

	sim_config_defaults(&cfg);
	sim_config_randomize(&cfg, 42);
	sim_field_defaults(&field);
	if (wall)
		cfg.start.x_mm = 1370.0;
	if (sim_init(&s, &cfg, &field) != 0) {
		fprintf(stderr, "sim_init failed\n");
		return 0.0;
	}
	t0 = clock();
	for (tick = 0; tick < ticks; tick++) {
		/* forward and back on a 2 s period, turning a little; or a steady push */
		int16_t d = wall ? 6000 : (int16_t)((tick % 2000) < 1000 ? 12000 : -12000);

		sim_set_duty(&s, d, (int16_t)(wall ? d : d - 1000));
		sim_advance_ns(&s, 1000000);
		sim_read_sensors(&s, &sens);
		checksum += sens.enc_count[0] + sens.enc_count[1] + sens.shock_mask;
	}
	t1 = clock();
	cpu = (double)(t1 - t0) / CLOCKS_PER_SEC;
	steps = (double)s.steps;
	printf("%-22s %10.0f substeps/s  %6.1f ns/substep  %7.0fx real time (checksum %u)\n", name,
	       steps / cpu, 1e9 * cpu / steps, sim_seconds / cpu, checksum);
	return steps / cpu;
}

int main(void)
{
	printf("substep 100 us, 10 substeps and one sensor read per 1 ms tick\n");
	run("open floor", false, 200.0);
	run("pushing on a border", true, 200.0);
	return 0;
}
