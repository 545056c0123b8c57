/* Real-time factor of the simulated board: the physics (sim/) and the control core
 * (firmware/core/) run in lockstep through the host port at 1 kHz, 10 physics substeps per tick,
 * on one core. Prints simulated seconds per wall-clock second, the split between physics and
 * core, and ns per tick; asserts nothing (issue 4 asks for at least 2000x real time).
 *
 * Build and run, Release (-O3) with link-time optimisation (the tick calls small functions of
 * other modules all along; without it the figures are some 8 % lower):
 *   cmake -S . -B build-realtime -G Ninja -DCMAKE_BUILD_TYPE=Release -DASSERV_TESTS=OFF \
 *     -DCMAKE_INTERPROCEDURAL_OPTIMIZATION=ON
 *   cmake --build build-realtime --target bench_realtime
 *   build-realtime/bench/bench_realtime [runs]
 * or bash bench/realtime.sh [runs], which does all three. On a shared or virtual machine the
 * figures vary by several percent from run to run: the median of several runs is printed.
 *
 * The mix: N_ROBOTS robots perturbed by sim_config_randomize() (seeds 1..N_ROBOTS), each driven
 * for ROBOT_S simulated seconds by a master that sends its orders through host_i2c_write() and
 * polls CHECK_BUSY at 100 Hz, at the annex's limits (SET_VITESSE_TRAJ 100 100, SET_VITESSE_ROT
 * 50 100): GOTO legs across the field at 1 m/s, short legs whose cost is the turn before them,
 * basket visits (GOTO to 350 mm of a basket, GOTO_PANIER into it: the push ends on the contact,
 * walls and switches active, then GOTO_REVERSE 150 mm) and idle pauses. Before each order the
 * master corrects the estimate with SET_NEW_POS from the simulator's truth (a beacon fix), so
 * that the randomized encoder errors do not drive the robot into a border over 100 s.
 *
 * Three timed phases, each run `runs` times (default 7), the median printed:
 *   - physics + core: the whole scenario with host_tick() (sensors, board_tick(), physics);
 *   - physics alone: the duties recorded in a first, untimed pass replayed on a fresh
 *     simulator (sim_read_sensors, sim_set_duty, sim_advance_ns per tick);
 *   - core alone: the recorded inputs and I2C transactions replayed into a fresh board
 *     (board_tick per tick).
 * Both replays are checked to give the recorded bits (last line).
 */
#define _POSIX_C_SOURCE 199309L
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "fixmath.h"
#include "host.h"
#include "port.h"

#define N_ROBOTS 6
#define ROBOT_S 100
#define TICKS_PER_ROBOT ((uint32_t)ROBOT_S * 1000u)
#define POLL_TICKS 10       /* the master reads CHECK_BUSY every 10 ms */
#define ORDER_TIMEOUT 20000 /* [ticks] then STOP */
/* Targets of the legs stay in this box [mm]: 350 mm from the long borders, 600 mm from the
 * ends, clear of both baskets for the robot's 196 mm reach. */
#define BOX_X_MM 900
#define BOX_Y_MM 500
#define BASKET_APPROACH_MM 350
#define MAX_XFER 8

/* One I2C transaction of the master, with the tick before which it happened. */
struct xfer {
	uint32_t tick;
	uint8_t read; /* 1: a read of n bytes; 0: a write of bytes[0..n) */
	uint8_t n;
	uint8_t stop;
	uint8_t bytes[MAX_XFER];
};

/* What the untimed pass records for the replays. */
struct record {
	struct board_inputs *in; /* [TICKS_PER_ROBOT] */
	int16_t (*duty)[2];      /* [TICKS_PER_ROBOT] */
	struct xfer *xfers;
	size_t n_xfers, cap_xfers;
	struct sim_truth end; /* after the last tick */
};

/* Counts over the recorded pass, to show the mix. */
struct mix {
	uint64_t state_ticks[6]; /* per ORDER_STATE_* */
	uint32_t legs, turns, baskets, idles, reverses;
	uint32_t ends[8]; /* per END_REASON_* */
	uint32_t timeouts;
};

struct robot {
	struct host h;
	struct sim_config sc;
	struct sim_field field;
	struct board_config bc;
	struct sim_rng rng; /* the master's choices */
	struct record *rec; /* NULL in the timed run */
	struct mix *mix;    /* NULL in the timed run */
};

static struct robot robot;
static struct host replay_host;
static struct sim replay_sim;
static struct record records[N_ROBOTS];
static struct mix the_mix;

static double now_s(void)
{
	struct timespec t;

	clock_gettime(CLOCK_MONOTONIC, &t);
	return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

static void log_xfer(struct robot *r, uint8_t read, const uint8_t *b, uint8_t n, int stop)
{
	struct record *rec = r->rec;
	struct xfer *x;

	if (!rec)
		return;
	if (rec->n_xfers == rec->cap_xfers) {
		rec->cap_xfers = rec->cap_xfers ? 2 * rec->cap_xfers : 4096;
		rec->xfers = realloc(rec->xfers, rec->cap_xfers * sizeof(*rec->xfers));
		if (!rec->xfers) {
			fprintf(stderr, "bench_realtime: out of memory\n");
			exit(1);
		}
	}
	x = &rec->xfers[rec->n_xfers++];
	x->tick = (uint32_t)r->h.ticks;
	x->read = read;
	x->n = n;
	x->stop = (uint8_t)stop;
	if (!read)
		memcpy(x->bytes, b, n);
}

static void bus_write(struct robot *r, const uint8_t *b, uint8_t n, int stop)
{
	log_xfer(r, 0, b, n, stop);
	host_i2c_write(&r->h, b, n, stop);
}

static void bus_read(struct robot *r, uint8_t *out, uint8_t n)
{
	log_xfer(r, 1, NULL, n, 1);
	host_i2c_read(&r->h, out, n);
}

/* One control period; 0 once the robot's simulated time is used up. */
static int tick(struct robot *r)
{
	uint32_t k = (uint32_t)r->h.ticks;

	if (k >= TICKS_PER_ROBOT)
		return 0;
	host_tick(&r->h);
	if (r->rec) {
		/* port_sample() reads the HAL, which still answers this tick's sensors. */
		port_sample(&r->rec->in[k]);
		r->rec->duty[k][0] = r->h.board.servo.last_out.duty_q15[0];
		r->rec->duty[k][1] = r->h.board.servo.last_out.duty_q15[1];
		r->mix->state_ticks[r->h.board.planner.orders.state % 6]++;
	}
	return 1;
}

static uint8_t status(struct robot *r)
{
	uint8_t s = 0;

	bus_write(r, (const uint8_t[]){PROTO_CHECK_BUSY}, 1, 0);
	bus_read(r, &s, 1);
	return s;
}

/* The master's `while (BUSY_TRAJET)`, polled every POLL_TICKS; STOP after ORDER_TIMEOUT. */
static void wait_idle(struct robot *r)
{
	uint32_t waited = 0;

	for (;;) {
		for (int i = 0; i < POLL_TICKS; i++)
			if (!tick(r))
				return;
		waited += POLL_TICKS;
		if (!(status(r) & STATUS_BUSY_TRAJET))
			break;
		if (waited == ORDER_TIMEOUT) {
			bus_write(r, (const uint8_t[]){PROTO_STOP}, 1, 1);
			if (r->mix)
				r->mix->timeouts++;
		}
	}
	if (r->mix)
		r->mix->ends[r->h.board.planner.orders.end_reason & 7]++;
}

static int32_t rand_in(struct robot *r, int32_t lo, int32_t hi)
{
	return lo + (int32_t)(sim_rng_next(&r->rng) % (uint64_t)(hi - lo + 1));
}

/* The beacon fix: SET_NEW_POS with the estimate's error (estimate - truth), mm and degrees. */
static void fix_pose(struct robot *r)
{
	struct odometry_pose est = board_get_pose(&r->h.board);
	struct sim_truth t;
	double ex, ey, ea;
	int16_t e[3];
	uint8_t m[7];

	sim_get_truth(&r->h.sim, &t);
	ex = 1e-3 * est.x_um - t.odo_pose.x_mm;
	ey = 1e-3 * est.y_um - t.odo_pose.y_mm;
	ea = fx_turn32_to_cdeg(est.heading_turn32) * 0.01 - t.odo_pose.heading_rad * 57.29577951;
	while (ea > 180.0)
		ea -= 360.0;
	while (ea < -180.0)
		ea += 360.0;
	e[0] = (int16_t)(ex < 0 ? ex - 0.5 : ex + 0.5);
	e[1] = (int16_t)(ey < 0 ? ey - 0.5 : ey + 0.5);
	e[2] = (int16_t)(ea < 0 ? ea - 0.5 : ea + 0.5);
	if (e[0] == 0 && e[1] == 0 && e[2] == 0)
		return;
	m[0] = PROTO_SET_NEW_POS;
	for (int i = 0; i < 3; i++) {
		m[1 + 2 * i] = (uint8_t)((uint16_t)e[i] >> 8);
		m[2 + 2 * i] = (uint8_t)e[i];
	}
	bus_write(r, m, 7, 1);
}

static void goto_mm(struct robot *r, int32_t x, int32_t y)
{
	uint8_t m[6] = {PROTO_GOTO, (uint8_t)((uint16_t)x >> 8),
			(uint8_t)x, (uint8_t)((uint16_t)y >> 8),
			(uint8_t)y, 0};

	bus_write(r, m, 6, 1);
	wait_idle(r);
}

/* A leg across the field to a random point of the box. */
static void leg(struct robot *r)
{
	if (r->mix)
		r->mix->legs++;
	goto_mm(r, rand_in(r, -BOX_X_MM, BOX_X_MM), rand_in(r, -BOX_Y_MM, BOX_Y_MM));
}

/* A short leg (150..300 mm) in a random direction: mostly the turn before it. */
static void turn(struct robot *r)
{
	struct odometry_pose p = board_get_pose(&r->h.board);
	int32_t x = 0, y = 0;

	if (r->mix)
		r->mix->turns++;
	for (int i = 0; i < 16; i++) {
		int32_t dx = rand_in(r, -300, 300), dy = rand_in(r, -300, 300);
		int32_t d2 = dx * dx + dy * dy;

		x = p.x_um / 1000 + dx;
		y = p.y_um / 1000 + dy;
		if (d2 >= 150 * 150 && d2 <= 300 * 300 && x >= -BOX_X_MM && x <= BOX_X_MM &&
		    y >= -BOX_Y_MM && y <= BOX_Y_MM)
			break;
		x = rand_in(r, -BOX_X_MM, BOX_X_MM);
		y = rand_in(r, -BOX_Y_MM, BOX_Y_MM);
	}
	goto_mm(r, x, y);
}

/* GOTO near a basket, GOTO_PANIER into it (contact and recalibration), back off. */
static void basket(struct robot *r)
{
	const struct sim_obstacle *b = &r->field.obstacles[rand_in(r, 0, 1)];
	/* from the basket toward the field's centre, +/- 30 degrees */
	double a = atan2(-b->y_mm, -b->x_mm) + rand_in(r, -30, 30) * (3.14159265358979 / 180.0);
	struct sim_truth t;
	int32_t half_deg;

	if (r->mix)
		r->mix->baskets++;
	goto_mm(r, (int32_t)lround(b->x_mm + BASKET_APPROACH_MM * cos(a)),
		(int32_t)lround(b->y_mm + BASKET_APPROACH_MM * sin(a)));
	fix_pose(r);
	/* The master aims at the basket's centre from where its beacon says the robot is (the
	 * GOTO ends a few mm off the approach point): with the one switch in the middle of the
	 * front, a 2 degree step of GOTO_PANIER is the aim's only error. */
	sim_get_truth(&r->h.sim, &t);
	half_deg = (int32_t)lround(atan2(b->y_mm - t.pose.y_mm, b->x_mm - t.pose.x_mm) *
				   (90.0 / 3.14159265358979));
	bus_write(r, (const uint8_t[]){PROTO_GOTO_PANIER, (uint8_t)(int8_t)half_deg}, 2, 1);
	wait_idle(r);
	if (r->mix)
		r->mix->reverses++;
	bus_write(r, (const uint8_t[]){PROTO_GOTO_REVERSE, 150}, 2, 1);
	wait_idle(r);
}

static void pause_idle(struct robot *r)
{
	int32_t n = rand_in(r, 300, 2000);

	if (r->mix)
		r->mix->idles++;
	for (int32_t i = 0; i < n; i++)
		if (!tick(r))
			return;
}

static int robot_init(struct robot *r, int seed, struct record *rec, struct mix *mix)
{
	sim_field_defaults(&r->field);
	sim_config_defaults(&r->sc);
	r->sc.coarse_substep_ns = 1000000; /* the speed runs' 1 ms substep away from contacts */
	/* the board believes the nominal robot at the nominal start; the truth is perturbed */
	host_board_config(&r->sc, &r->field, &r->bc);
	sim_config_randomize(&r->sc, (uint64_t)seed);
	sim_rng_seed(&r->rng, 1000u + (uint64_t)seed);
	r->rec = rec;
	r->mix = mix;
	return host_init(&r->h, &r->bc, &r->sc, &r->field);
}

/* The master's program, until the robot's time is used up. */
static void scenario(struct robot *r)
{
	bus_write(r, (const uint8_t[]){PROTO_SET_VITESSE_TRAJ, 100, 100}, 3, 1);
	bus_write(r, (const uint8_t[]){PROTO_SET_VITESSE_ROT, 50, 100}, 3, 1);
	while (r->h.ticks < TICKS_PER_ROBOT) {
		int32_t pick = rand_in(r, 0, 99);

		fix_pose(r);
		if (pick < 50)
			leg(r);
		else if (pick < 72)
			turn(r);
		else if (pick < 87)
			basket(r);
		else
			pause_idle(r);
	}
}

static void record_all(void)
{
	for (int i = 0; i < N_ROBOTS; i++) {
		struct record *rec = &records[i];

		rec->in = malloc(TICKS_PER_ROBOT * sizeof(*rec->in));
		rec->duty = malloc(TICKS_PER_ROBOT * sizeof(*rec->duty));
		if (!rec->in || !rec->duty || robot_init(&robot, i + 1, rec, &the_mix)) {
			fprintf(stderr, "bench_realtime: setup failed\n");
			exit(1);
		}
		scenario(&robot);
		sim_get_truth(&robot.h.sim, &rec->end);
	}
}

/* Phase 1: the whole thing. Returns the wall time; *same: the truth is the recorded one. */
static double run_full(int *same)
{
	double t = 0.0;
	struct sim_truth end;

	for (int i = 0; i < N_ROBOTS; i++) {
		double t0;

		if (robot_init(&robot, i + 1, NULL, NULL))
			exit(1);
		t0 = now_s();
		scenario(&robot);
		t += now_s() - t0;
		sim_get_truth(&robot.h.sim, &end);
		*same &= memcmp(&end, &records[i].end, sizeof(end)) == 0;
	}
	return t;
}

/* Phase 2: the simulator alone on the recorded duties, in host_tick()'s order. */
static double run_physics(int *same, unsigned *checksum)
{
	double t = 0.0;
	struct sim_truth end;
	struct sim_sensors sens;

	for (int i = 0; i < N_ROBOTS; i++) {
		const struct record *rec = &records[i];
		uint64_t tick_ns;
		double t0;

		if (robot_init(&robot, i + 1, NULL, NULL) ||
		    sim_init(&replay_sim, &robot.sc, &robot.field))
			exit(1);
		tick_ns = robot.h.tick_ns;
		t0 = now_s();
		for (uint32_t k = 0; k < TICKS_PER_ROBOT; k++) {
			sim_read_sensors(&replay_sim, &sens);
			*checksum += sens.enc_count[0] + sens.shock_mask + sens.line_mask;
			sim_set_duty(&replay_sim, rec->duty[k][0], rec->duty[k][1]);
			sim_advance_ns(&replay_sim, tick_ns);
		}
		t += now_s() - t0;
		sim_get_truth(&replay_sim, &end);
		*same &= memcmp(&end, &rec->end, sizeof(end)) == 0;
	}
	return t;
}

/* Phase 3: the core alone on the recorded inputs, with the master's transactions. */
static double run_core(int *same)
{
	double t = 0.0;
	uint8_t buf[32];

	for (int i = 0; i < N_ROBOTS; i++) {
		const struct record *rec = &records[i];
		struct board_outputs out;
		size_t x = 0;
		double t0;

		if (robot_init(&robot, i + 1, NULL, NULL) ||
		    host_init(&replay_host, &robot.bc, &robot.sc, &robot.field))
			exit(1);
		t0 = now_s();
		for (uint32_t k = 0; k < TICKS_PER_ROBOT; k++) {
			for (; x < rec->n_xfers && rec->xfers[x].tick == k; x++) {
				const struct xfer *f = &rec->xfers[x];

				if (f->read)
					host_i2c_read(&replay_host, buf, f->n);
				else
					host_i2c_write(&replay_host, f->bytes, f->n, f->stop);
			}
			board_tick(&replay_host.board, &rec->in[k], &out);
			*same &= out.duty_q15[0] == rec->duty[k][0] &&
				 out.duty_q15[1] == rec->duty[k][1];
		}
		t += now_s() - t0;
	}
	return t;
}

static int cmp_double(const void *a, const void *b)
{
	double x = *(const double *)a, y = *(const double *)b;

	return x < y ? -1 : x > y;
}

static void print_phase(const char *name, double *t, int runs)
{
	const double sim_s = (double)N_ROBOTS * ROBOT_S;
	const double ticks = (double)N_ROBOTS * TICKS_PER_ROBOT;
	double med;

	qsort(t, (size_t)runs, sizeof(*t), cmp_double);
	med = t[runs / 2];
	printf("  %-34s %7.0fx real time  %6.0f ns/tick  (best %.0fx)\n", name, sim_s / med,
	       1e9 * med / ticks, sim_s / t[0]);
}

int main(int argc, char **argv)
{
	int runs = argc > 1 ? atoi(argv[1]) : 7;
	double t_full[64], t_phys[64], t_core[64], total = 0.0;
	int same_full = 1, same_phys = 1, same_core = 1;
	unsigned checksum = 0;
	const struct mix *m = &the_mix;
	static const char *const state_names[6] = {"idle",   "rotate", "translate",
						   "settle", "push",   "stopping"};

	if (runs < 1 || runs > 64) {
		fprintf(stderr, "usage: bench_realtime [runs 1..64]\n");
		return 2;
	}
	record_all();
	for (int i = 0; i < 6; i++)
		total += (double)m->state_ticks[i];
	printf("bench_realtime: %d robots (sim_config_randomize seeds 1..%d) x %d s simulated, "
	       "1 kHz control, 10 physics substeps per tick, one core\n",
	       N_ROBOTS, N_ROBOTS, ROBOT_S);
	printf("mix: %u GOTO legs, %u short legs (turns), %u basket visits (GOTO, GOTO_PANIER, "
	       "GOTO_REVERSE), %u idle pauses\n",
	       m->legs, m->turns, m->baskets, m->idles);
	printf("     ends: %u DONE, %u BASKET, %u SHOCK, %u MOTOR, %u FAULT, %u timeouts\n",
	       m->ends[END_REASON_DONE], m->ends[END_REASON_BASKET], m->ends[END_REASON_SHOCK],
	       m->ends[END_REASON_MOTOR], m->ends[END_REASON_FAULT], m->timeouts);
	printf("     time:");
	for (int i = 0; i < 6; i++)
		printf(" %s %.1f %%%s", state_names[i], 100.0 * (double)m->state_ticks[i] / total,
		       i < 5 ? "," : "\n");
	for (int i = 0; i < runs; i++) {
		t_full[i] = run_full(&same_full);
		t_phys[i] = run_physics(&same_phys, &checksum);
		t_core[i] = run_core(&same_core);
	}
	printf("median of %d runs:\n", runs);
	print_phase("physics + core (host_tick)", t_full, runs);
	print_phase("physics alone (sim, replayed)", t_phys, runs);
	print_phase("core alone (board_tick, replayed)", t_core, runs);
	printf("same bits as the recorded pass: full run %s, physics %s, core %s (checksum %u)\n",
	       same_full ? "yes" : "NO", same_phys ? "yes" : "NO", same_core ? "yes" : "NO",
	       checksum);
	return 0;
}
