/* pid_update and control_update as the AVR runs them (with firmware/arch/avr's
 * kernels) against the host's portable C, bit for bit: control_avr.elf in simavr applies each
 * operation (init, settings, reset, update) sent through a mailbox in its RAM to its own pid and
 * control, the host applies it to its own (control_avr/control_ops.c on both), and the return
 * value and the state after it must be equal. Edge cases around the fast paths' bounds (the
 * errors and differences where P or D leave the 16-bit path, the 16-bit previous error, the
 * clips at 8 full duties, the feed-forward's coefficients at 2^16 and its rounding ties), then a
 * fixed-seed random sweep of gains, limits, rates, resets and errors. test_pid and test_control
 * check the portable C itself; test_avr_annex, one session of the whole firmware. Also prints
 * the cycles of each operation on the AVR. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include <cmocka.h>

#include "control_avr/control_avr.h"
#include "fixmath_avr/fixmath_avr.h"
#include "mailbox.h"

#define RANDOM_ROUNDS 600u
#define STEPS_PER_ROUND 60
#define MAX_CYCLES_PER_OP 200000u

static const char *elf_path;

static const char *const op_name[CTA_OPS] = {
	[CTA_NOP] = "(mailbox)",
	[CTA_PID_INIT] = "pid_init",
	[CTA_PID_SET] = "pid_set_config",
	[CTA_PID_RESET] = "pid_reset",
	[CTA_PID_UPDATE] = "pid_update",
	[CTA_PID_RAW_D] = "pid_set_raw_d",
	[CTA_CTL_INIT] = "control_init",
	[CTA_CTL_GAINS] = "control_set_gains",
	[CTA_CTL_PRESET] = "control_set_gains (preset)",
	[CTA_CTL_RESET] = "control_reset",
	[CTA_CTL_OFF] = "control_off",
	[CTA_CTL_UPDATE] = "control_update",
	[CTA_CTL_RAW_D] = "control_raw_d",
	[CTA_ODO_ADVANCE] = "odometry_advance",
};

struct target {
	struct mailbox mb;
	struct cta_state host; /* the host's pid and control, in step with the AVR's */
	uint64_t n[CTA_OPS], cycles[CTA_OPS], max[CTA_OPS];
	/* pid_update calls that the fast path takes, and the others; control_update calls with
	 * coefficients below 2^16 (ff_term_avr) and the others */
	uint64_t pid_fast, pid_general, ff_narrow, ff_wide;
};

static int target_open(struct target *t)
{
	memset(t, 0, sizeof(*t));
	return mailbox_open(&t->mb, elf_path);
}

static void on_avr(struct target *t, uint8_t op, const int32_t *arg, int32_t *res)
{
	uint8_t *box = t->mb.avr->data + t->mb.box;
	uint64_t start;

	for (int i = 0; i < CTA_N_ARGS; i++)
		for (int b = 0; b < 4; b++)
			box[CTA_OFF_ARGS + 4 * i + b] = (uint8_t)((uint32_t)arg[i] >> (8 * b));
	memset(box + CTA_OFF_RES, 0xa5, 4 * CTA_N_RES);
	start = t->mb.avr->cycle;
	box[CTA_OFF_OP] = op;
	if (mailbox_run_until(&t->mb, (uint16_t)(t->mb.box + CTA_OFF_OP), 0, MAX_CYCLES_PER_OP))
		fail_msg("%s: the AVR did not finish", op_name[op]);
	t->n[op]++;
	t->cycles[op] += t->mb.avr->cycle - start;
	if (t->mb.avr->cycle - start > t->max[op])
		t->max[op] = t->mb.avr->cycle - start;
	for (int i = 0; i < CTA_N_RES; i++) {
		const uint8_t *p = box + CTA_OFF_RES + 4 * i;

		res[i] = (int32_t)((uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 |
				   (uint32_t)p[3] << 24);
	}
}

/* |v| <= lim, as pid.c's within16. */
static int within(int32_t v, int32_t lim)
{
	return v >= -lim && v <= lim;
}

/* Whether pid_update(c, e) takes the fast path (arch/avr/arch_pid.h: pid_arch_update_small;
 * pid.c: pid_update_c). */
static int takes_fast_path(const struct pid *c, int32_t e)
{
	int32_t de;

	if (pid_d_filtered(c) || !within(e, c->fast.p_err_um))
		return 0;
	if (c->has_prev == 1)
		return 0;
	de = c->has_prev ? e - c->prev_err_um : 0; /* both in 16 bits here */
	return within(de, c->fast.d_err_um);
}

/* op on both, the same arguments (unused ones 0): every result must be equal. */
static int32_t check(struct target *t, uint8_t op, const int32_t *args, int n_args)
{
	int32_t arg[CTA_N_ARGS] = {0}, got[CTA_N_RES], want[CTA_N_RES];

	memcpy(arg, args, (size_t)n_args * sizeof(*arg));
	if (op == CTA_PID_UPDATE) {
		if (takes_fast_path(&t->host.pid, arg[0]))
			t->pid_fast++;
		else
			t->pid_general++;
	} else if (op == CTA_CTL_UPDATE) {
		if (t->host.ctl.ff_narrow)
			t->ff_narrow++;
		else
			t->ff_wide++;
	}
	on_avr(t, op, arg, got);
	cta_run(&t->host, op, arg, want);
	for (int i = 0; i < CTA_N_RES; i++)
		if (got[i] != want[i]) {
			char what[200];
			int len = 0;

			for (int k = 0; k < n_args && len < 180; k++)
				len += snprintf(what + len, sizeof(what) - (size_t)len, " %ld",
						(long)arg[k]);
			fail_msg("%s(%s): result %d: AVR %ld, host %ld (call %llu of it)",
				 op_name[op], what, i, (long)got[i], (long)want[i],
				 (unsigned long long)t->n[op]);
		}
	return want[0];
}

#define CHECK(t, op, ...)                                                                          \
	check(t, op, (const int32_t[]){__VA_ARGS__},                                               \
	      (int)(sizeof((const int32_t[]){__VA_ARGS__}) / sizeof(int32_t)))

static int32_t pid_update_both(struct target *t, int32_t e)
{
	return CHECK(t, CTA_PID_UPDATE, e);
}

/* The errors where pid_update changes path or clips, for the pid's present gains. */
static size_t pid_edges(const struct pid *c, int32_t *out)
{
	const int32_t fixed[] = {0,     1,       2,       32767,   32768,    65535,
				 65536, 4194303, 4194304, 4194305, INT32_MAX};
	const int32_t bounds[] = {c->fast.p_err_um, c->fast.d_err_um, c->p_err_max_um,
				  c->d_err_max_um};
	size_t n = 0;

	for (size_t i = 0; i < sizeof(fixed) / sizeof(fixed[0]); i++) {
		out[n++] = fixed[i];
		out[n++] = -fixed[i];
	}
	out[n++] = INT32_MIN;
	for (size_t i = 0; i < sizeof(bounds) / sizeof(bounds[0]); i++)
		for (int32_t d = 0; d <= 1; d++) {
			out[n++] = bounds[i] + d;
			out[n++] = -bounds[i] - d;
		}
	return n;
}

/* Each pair of edge errors as two ticks after a reset (the second one's difference at the
 * bounds of D), then a third tick at the same error (the integral), for gains that make each
 * byte of kp, kd and ki zero or not, at the rates' bounds, and the limits' bounds. */
static void test_pid_edges(void **state)
{
	struct target *t = *state;
	/* p, i, d, limit, rate, then the derivative's low-pass: d_shift and d_lag_max_um */
	static const int32_t cfgs[][7] = {
		{205, 400, 160, 32767, 1000},
		{65535, 65535, 65535, 32767, 100},
		{65535, 65535, 65535, 1, 2000},
		{1, 1, 1, 32767, 1000},
		{0, 0, 0, 100, 1000},
		{5000, 0, 65535, 32767, 2000},
		{300, 65535, 0, 20000, 100},
		{12, 3000, 40, 5, 1000},
		{400, 1200, 250, 32767, 1000},
		{31250, 7, 2000, 16384, 500},
		{205, 400, 160, 32767, 1000, 4, 320},
		{65535, 65535, 65535, 32767, 100, 6, 4194304},
		{400, 1200, 250, 32767, 2000, 1, 1},
		{65535, 0, 65535, 32767, 2000, 6, 4194304},
	};
	int32_t e[64];

	for (size_t k = 0; k < sizeof(cfgs) / sizeof(cfgs[0]); k++) {
		const int32_t *g = cfgs[k];
		size_t n;

		assert_int_equal(CHECK(t, CTA_PID_INIT, g[0], g[1], g[2], g[3], g[4], g[5], g[6]),
				 0);
		n = pid_edges(&t->host.pid, e);
		for (size_t i = 0; i < n; i++)
			for (size_t j = 0; j < n; j++) {
				CHECK(t, CTA_PID_RESET, 0);
				pid_update_both(t, e[i]);
				pid_update_both(t, e[j]);
				pid_update_both(t, e[j]);
			}
	}
}

/* The feed-forward's coefficients per m/s around 2^16 per um/s * 2^20 (62 499 gives 65 535,
 * 62 500 gives 65 536), and velocities and accelerations at the profiles' bounds and at the
 * rounding's ties (k = 1: v = +-2^19); half of them with the derivative's low-pass. */
static void test_control_edges(void **state)
{
	struct target *t = *state;
	static const int32_t coef[] = {0, 1, 2, 1000, 19980, 62499, 62500, 999999, 1000000};
	static const int32_t v[] = {0,       1,        -1,        524287,    524288,  -524288,
				    -524289, 16777215, -16777216, -16777215, 8388608, -3000000};
	const size_t nc = sizeof(coef) / sizeof(coef[0]), nv = sizeof(v) / sizeof(v[0]);

	for (size_t a = 0; a < nc; a++)
		for (size_t b = 0; b < nc; b++) {
			assert_int_equal(CHECK(t, CTA_CTL_INIT, 1000, 32767, coef[a], coef[b],
					       coef[nc - 1 - b], 205, 400, 160, 40, 0, 60, 400,
					       1200, 250, 131800, (a + b) % 2 ? 16 : 0, 320),
					 0);
			for (size_t i = 0; i < nv; i++)
				for (size_t j = 0; j < nv; j++)
					CHECK(t, CTA_CTL_UPDATE, 100, v[i], v[j], -50, v[j], v[i],
					      0, 0);
		}
}

/* xorshift32: the same sequence on every run. */
static uint32_t rng_state = 2463534242u;

static uint32_t rnd(void)
{
	rng_state ^= rng_state << 13;
	rng_state ^= rng_state >> 17;
	rng_state ^= rng_state << 5;
	return rng_state;
}

static uint32_t below(uint32_t n)
{
	return rnd() % n;
}

/* A value of a random bit length (0..bits_max), of a random sign. */
static int32_t val(unsigned bits_max)
{
	unsigned b = below(bits_max + 1);
	uint32_t m = b >= 32 ? rnd() : rnd() & (((uint32_t)1 << b) - 1);
	int32_t v = (int32_t)(m & 0x7fffffffu);

	return rnd() & 1 ? -v : v;
}

/* The next error: an edge of the pid's (its bounds, +-1), near the last one (small
 * differences, within the D bounds or not), or anywhere. */
static int32_t err_val(const struct pid *c, int32_t prev)
{
	int32_t edge[64], d;
	uint32_t k = below(16);

	if (k == 0)
		return edge[below((uint32_t)pid_edges(c, edge))];
	if (k == 1) {
		int32_t b = below(2) ? c->fast.d_err_um : c->fast.p_err_um;

		return prev + (rnd() & 1 ? b : -b) + (int32_t)below(3) - 1;
	}
	if (k < 9) {
		d = val(k < 4 ? 6 : k < 6 ? 12 : 17);
		if ((prev > 0 && d > INT32_MAX - prev) || (prev < 0 && d < INT32_MIN - prev))
			return prev;
		return prev + d;
	}
	if (k < 14)
		return val(16);
	return val(31);
}

static uint16_t gain(void)
{
	uint32_t k = below(8);

	if (k == 0)
		return 0;
	if (k == 1)
		return (uint16_t)rnd();
	if (k == 2)
		return 65535;
	return (uint16_t)below(k < 5 ? 500 : 5000);
}

static int16_t limit(void)
{
	uint32_t k = below(4);

	return k == 0 ? 32767 : k == 1 ? (int16_t)(1 + below(100)) : (int16_t)(1 + below(32767));
}

static uint16_t hz(void)
{
	uint32_t k = below(4);

	return k == 0 ? 1000 : k == 1 ? (rnd() & 1 ? 100 : 2000) : (uint16_t)(100 + below(1901));
}

/* The derivative's low-pass: none, or 2^1..2^6 ticks; now and then 2^7 (refused). */
static int32_t d_shift(void)
{
	uint32_t k = below(8);

	return k < 2 ? 0 : k < 7 ? (int32_t)(1 + below(6)) : 7;
}

/* Its largest lag [um]: the robot's, a count, anywhere up to its bound; now and then 0
 * (refused with a low-pass). */
static int32_t d_lag(void)
{
	uint32_t k = below(10);

	return k == 0  ? 0
	       : k < 3 ? 320
	       : k < 5 ? 1
	       : k < 7 ? 4194304
		       : (int32_t)(1 + below(4194304));
}

static void pid_round(struct target *t)
{
	int32_t prev = 0;

	/* now and then out of range (a limit of 0, a rate of 99): refused on both */
	if (CHECK(t, CTA_PID_INIT, gain(), gain(), gain(), below(30) ? limit() : 0,
		  below(30) ? hz() : 99, d_shift(), d_lag()))
		return;
	for (int s = 0; s < STEPS_PER_ROUND; s++) {
		uint32_t k = below(100);

		if (k == 0)
			CHECK(t, CTA_PID_RESET, 0);
		else if (k == 1)
			CHECK(t, CTA_PID_SET, gain(), gain(), gain(), limit(),
			      below(4) ? t->host.pid.cfg.tick_hz : hz(),
			      below(2) ? t->host.pid.cfg.d_shift : d_shift(), d_lag());
		else if (k < 4)
			CHECK(t, CTA_PID_RAW_D, (int32_t)below(2));
		else
			pid_update_both(t, prev = err_val(&t->host.pid, prev));
	}
}

/* A feed-forward coefficient per m/s, often at or near 2^16 per um/s * 2^20, and a velocity
 * or acceleration within the profiles' bounds (2^24), at them, or a little beyond. */
static int32_t ff_coef(void)
{
	uint32_t k = below(6);

	if (k == 0)
		return 0;
	if (k == 1)
		return 1000000 - (int32_t)below(3);
	if (k == 2)
		return (int32_t)below(1000001);
	return (int32_t)below(62600);
}

static int32_t ff_val(void)
{
	uint32_t k = below(10);

	if (k == 0)
		return val(26);
	if (k == 1)
		return rnd() & 1 ? 16777215 : -16777216 + (int32_t)below(3);
	return val(24);
}

static void control_round(struct target *t)
{
	int32_t g[9], sp[6] = {0}, m[2] = {0, 0};
	int32_t fs = ff_coef(), fa = ff_coef(), fan = ff_coef(), h = hz(), l = limit();
	/* The gain slew: 1 a tick at most, the robot's, or at its bound (2^24 [duty_q15/s]). */
	static const int32_t slews[] = {1, 131800, (int32_t)1 << 24};
	int32_t sl = slews[below(3)];
	/* The derivative's low-pass [ms]: none, the robot's, or any */
	int32_t df = below(3) == 0 ? 0 : below(2) ? 16 : (int32_t)below(256), dl = d_lag();

	for (int j = 0; j < 9; j++)
		g[j] = gain();
	if (below(3) == 0) { /* the robot's own settings (firmware/ports/avr/robot.c) */
		static const int32_t robot[9] = {205, 400, 160, 40, 0, 60, 400, 1200, 250};

		memcpy(g, robot, sizeof(g));
		fs = 19980, fa = 1400, fan = 900, h = 1000, l = 32767, sl = 131800;
		df = 16, dl = 320;
	}
	if (below(20) == 0)
		l = -(int32_t)below(3);
	if (CHECK(t, CTA_CTL_INIT, h, l, fs, fa, fan, g[0], g[1], g[2], g[3], g[4], g[5], g[6],
		  g[7], g[8], sl, df, dl))
		return;
	for (int s = 0; s < STEPS_PER_ROUND; s++) {
		uint32_t k = below(100);

		if (k == 0) {
			CHECK(t, CTA_CTL_RESET, 0);
		} else if (k == 1) {
			CHECK(t, CTA_CTL_OFF, 0);
		} else if (k == 2) {
			CHECK(t, CTA_CTL_PRESET, below(4));
		} else if (k == 3) {
			CHECK(t, CTA_CTL_GAINS, gain(), gain(), gain());
		} else if (k < 6) {
			CHECK(t, CTA_CTL_RAW_D, (int32_t)below(4));
		} else {
			const struct pid *axis[2] = {&t->host.ctl.dist, &t->host.ctl.angle};

			for (int j = 0; j < 2; j++) {
				int32_t e = err_val(axis[j], sp[3 * j] - m[j]);

				if (e > ((int32_t)1 << 30) || e < -((int32_t)1 << 30))
					e /= 4;
				m[j] = (int32_t)below((uint32_t)1 << 29) - ((int32_t)1 << 28);
				sp[3 * j] = m[j] + e;
				sp[3 * j + 1] = ff_val();
				sp[3 * j + 2] = ff_val();
			}
			CHECK(t, CTA_CTL_UPDATE, sp[0], sp[1], sp[2], sp[3], sp[4], sp[5], m[0],
			      m[1]);
		}
	}
}

/* odometry_advance along arcs of a tick and of a period (planner.c integrates the position once
 * per period with two rates): small and large wheel travels, either way, with heading changes
 * around each of the arc correction's paths (none below 2^15 turn * 2^-32, 32 bits below 2^24,
 * 64 bits above), from the position and kept sine and cosine of the last arc. The first arc is
 * one that a 16-bit int product in the 32-bit path once got wrong on the AVR. */
static void test_odometry_arcs(void **state)
{
	struct target *t = *state;
	const int32_t t_bits[] = {14, 15, 20, 23, 24, 25, 28, 31};
	int32_t x = -1, y = 0, xf = 46594, yf = 0, trig[3] = {0, 0, 1 << 30};

	CHECK(t, CTA_ODO_ADVANCE, 2573592, 2573593, 13996990, 441192811, x, y, xf, yf, trig[0],
	      trig[1], trig[2]);
	for (uint32_t n = 0; n < 20u * RANDOM_ROUNDS; n++) {
		int32_t l = val(below(4) ? 24 : 31), r = below(4) ? l + val(16) : val(31);
		int32_t dtheta = val((unsigned)t_bits[below(8)]);
		uint32_t heading = below(4) ? rnd() : (uint32_t)trig[0] + (uint32_t)(dtheta / 2);
		int32_t args[11];
		const struct odometry_position *o = &t->host.odo;

		if (below(8) == 0) {
			l = below(2) ? INT32_MAX : INT32_MIN;
			r = below(2) ? l : -l;
		}
		if (below(8) == 0) {
			x = (int32_t)rnd();
			y = (int32_t)rnd();
		}
		args[0] = l, args[1] = r, args[2] = dtheta, args[3] = (int32_t)heading;
		args[4] = x, args[5] = y, args[6] = xf, args[7] = yf;
		args[8] = trig[0], args[9] = trig[1], args[10] = trig[2];
		check(t, CTA_ODO_ADVANCE, args, 11); /* the host's state is the AVR's after it */
		x = (int32_t)o->x_um, y = (int32_t)o->y_um, xf = o->x_frac, yf = o->y_frac;
		trig[0] = (int32_t)o->trig_turn32, trig[1] = o->trig_sin_q30,
		trig[2] = o->trig_cos_q30;
	}
}

static void test_random(void **state)
{
	struct target *t = *state;

	for (uint32_t n = 0; n < RANDOM_ROUNDS; n++) {
		pid_round(t);
		control_round(t);
	}
}

static int setup(void **state)
{
	static struct target t;

	if (target_open(&t)) {
		fprintf(stderr, "cannot run %s in simavr\n", elf_path);
		return -1;
	}
	*state = &t;
	return 0;
}

/* The cycles of each operation, the mailbox's own (CTA_NOP) taken off; and how often each path
 * was taken, so that a sweep that missed one shows. */
static int report(void **state)
{
	struct target *t = *state;
	const int32_t none[1] = {0};
	int32_t res[CTA_N_RES];
	double base;

	on_avr(t, CTA_NOP, none, res);
	base = (double)t->cycles[CTA_NOP];
	printf("cycles on the AVR per call (mean, max), over the calls tried:\n");
	for (int op = CTA_NOP + 1; op < CTA_OPS; op++)
		if (t->n[op] != 0)
			printf("  %-20s %7.1f %7.0f   (%llu calls)\n", op_name[op],
			       (double)t->cycles[op] / (double)t->n[op] - base,
			       (double)t->max[op] - base, (unsigned long long)t->n[op]);
	printf("pid_update: %llu on the fast path, %llu not; control_update: %llu with the "
	       "narrow feed-forward, %llu the wide\n",
	       (unsigned long long)t->pid_fast, (unsigned long long)t->pid_general,
	       (unsigned long long)t->ff_narrow, (unsigned long long)t->ff_wide);
	return 0;
}

int main(int argc, char **argv)
{
	const struct CMUnitTest tests[] = {
		cmocka_unit_test(test_pid_edges),
		cmocka_unit_test(test_control_edges),
		cmocka_unit_test(test_random),
		cmocka_unit_test(test_odometry_arcs),
	};

	if (argc != 2) {
		fprintf(stderr, "usage: %s control_avr.elf\n", argv[0]);
		return 2;
	}
	elf_path = argv[1];
	return cmocka_run_group_tests(tests, setup, report);
}
