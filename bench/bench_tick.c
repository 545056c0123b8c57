/* Runs the board's control tick against the simulator in one scenario, so that callgrind can
 * count the instructions of board_tick() alone (bench/tick_instructions.sh). */
#include <stdio.h>
#include <string.h>

#include "host.h"

static void send(struct host *h, const uint8_t *b, uint8_t n)
{
	host_i2c_write(h, b, n, 1);
}

int main(int argc, char **argv)
{
	static struct host h;
	struct sim_config sc;
	struct sim_field f;
	struct board_config bc;
	const char *scenario = argc > 1 ? argv[1] : "goto";
	uint32_t ticks = 3000;

	sim_field_defaults(&f);
	sim_config_defaults(&sc);
	host_board_config(&sc, &f, &bc);
	if (host_init(&h, &bc, &sc, &f)) {
		fprintf(stderr, "bench_tick: host_init failed\n");
		return 1;
	}
	send(&h, (const uint8_t[]){PROTO_SET_VITESSE_TRAJ, 100, 100}, 3);
	send(&h, (const uint8_t[]){PROTO_SET_VITESSE_ROT, 50, 100}, 3);
	if (strcmp(scenario, "goto") == 0) {
		/* The annex's GOTO 200,100: 1.5 m at 1 m/s, braking included. */
		send(&h, (const uint8_t[]){PROTO_GOTO, 0, 200, 0, 100, 0}, 6);
	} else if (strcmp(scenario, "rotate") == 0) {
		send(&h, (const uint8_t[]){PROTO_GOTO_PANIER, 90}, 2);
		ticks = 1500;
	} else if (strcmp(scenario, "idle") != 0) {
		fprintf(stderr, "bench_tick: scenario must be idle, goto or rotate, not '%s'\n",
			scenario);
		return 2;
	}
	for (uint32_t i = 0; i < ticks; i++)
		host_tick(&h);
	printf("%s %u\n", scenario, (unsigned)ticks);
	return 0;
}
