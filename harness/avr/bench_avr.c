/* Benchmark of the AVR binary in simavr (prints, asserts nothing).
 *
 * The robot drives 2.4 m straight at 1 m/s (1 m/s^2) while a master polls CHECK_BUSY every
 * 10 ms and reads POSITION every 20 ms over I2C at 100 kHz. The run uses the exact lockstep
 * (avrsim.h), in which the tick takes no time for the physics: the robot follows its profile
 * whatever the tick costs, so that the tick's cycles are those of the real motion even when the
 * binary could not keep up in real time. Interrupts do not preempt the tick there; each is
 * measured on its own, and the load of a control period in real time is their sum:
 *     tick + (edges per period x encoder interrupt) + timer (1) + TWI per period.
 * With two rates (the binary's cfg.slow_shift > 0) the tick is the servo, and the slow steps
 * that run once every 2^slow_shift periods add their share:
 *     (servo + interrupts per period) / period + slow steps / slow period,
 * the mean from the means and the worst from the worst servo, the worst interrupt load and the
 * longest run of the slow steps. The same loads as measured are printed too: the servo and the
 * interrupts in one period (compare match to compare match), and every cycle awake in
 * 2^slow_shift consecutive periods, with the busiest of each.
 * Printed: the tick's cycles (mean, worst; over the move and at 1 m/s, i.e. while the true
 * speed is at least 0.95 m/s, until it falls below 0.9 m/s: the real-time lockstep's true speed
 * wavers by a few mm/s about the 0.95 on the way up), that load in % of the period at the binary's
 * rate, each interrupt's cycles, the TWI's cycles per bus event and the clock it holds, flash, RAM
 * and stack, the functions the tick (and the slow steps) spend their cycles in (mean, and in the
 * longest run), and the overruns the binary counted.
 * --realtime runs the same move in the real-time lockstep instead (avrsim.h): the binary must
 * then keep up, and the overruns at the end say whether it did.
 *   bench_avr asserv_avr.elf [--no-profile] [--realtime] */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "avrsim.h"
#include "m1284p.h"
#include "robot.h"

#define CRUISE_MM_S 950.0
#define CRUISE_END_MM_S 900.0

struct phase {
	struct avrsim_stats st;
	uint64_t ticks;
};

static void add(struct avrsim_count *a, const struct avrsim_count *b)
{
	a->n += b->n;
	a->cycles += b->cycles;
	if (b->max > a->max)
		a->max = b->max;
}

/* Adds the figures of a part of the run to the whole's. */
static void merge(struct phase *all, const struct avrsim_stats *s, uint64_t ticks)
{
	struct avrsim_stats *a = &all->st;

	a->cycles += s->cycles;
	a->idle += s->idle;
	add(&a->tick, &s->tick);
	add(&a->servo, &s->servo);
	add(&a->servo_slow, &s->servo_slow);
	add(&a->servo_handover, &s->servo_handover);
	add(&a->servo_other, &s->servo_other);
	add(&a->slow, &s->slow);
	add(&a->period, &s->period);
	add(&a->isr_sum, &s->isr_sum);
	add(&a->fast, &s->fast);
	add(&a->window, &s->window);
	for (int i = 0; i < 64; i++)
		add(&a->isr[i], &s->isr[i]);
	for (int i = 0; i < 32; i++) {
		add(&a->twi[i], &s->twi[i]);
		add(&a->stretch[i], &s->stretch[i]);
	}
	a->twi_bytes += s->twi_bytes;
	a->edges += s->edges;
	add(&a->edge_wait, &s->edge_wait);
	if (s->sp_min < a->sp_min)
		a->sp_min = s->sp_min;
	all->ticks += ticks;
}

static double mean(const struct avrsim_count *c)
{
	return c->n ? (double)c->cycles / (double)c->n : 0.0;
}

/* Interrupt cycles per control period, from each interrupt's count per period and its mean and
 * longest run: the mean; the worst, the TWI's from each kind of bus event's rate and its longest
 * run (the bus events differ: a STOP that takes a message costs three times a byte sent); the
 * cruder worst with every TWI interrupt at the longest of any kind; the encoders' part of the
 * worst. */
struct isr_load {
	double mean, worst, worst_all_twi, worst_encoders;
};

static struct isr_load isr_load(const struct phase *p)
{
	const uint8_t vec[] = {m1284p.vec_pcint[0], m1284p.vec_pcint[1], m1284p.vec_pcint[2],
			       m1284p.vec_pcint[3], m1284p.vec_twi,      m1284p.vec_timer3_compa};
	struct isr_load l = {0.0, 0.0, 0.0, 0.0};

	for (size_t i = 0; i < sizeof(vec); i++) {
		const struct avrsim_count *c = &p->st.isr[vec[i]];
		double per = (double)c->n / (double)p->ticks, w = per * (double)c->max;

		l.mean += per * mean(c);
		l.worst_all_twi += w;
		if (i < 4)
			l.worst_encoders += w;
		if (vec[i] != m1284p.vec_twi) {
			l.worst += w;
			continue;
		}
		for (int k = 0; k < 32; k++)
			l.worst += (double)p->st.twi[k].n / (double)p->ticks *
				   (double)p->st.twi[k].max;
	}
	return l;
}

/* One rate: the tick, the interrupts, and the load of a period. */
static void print_one_rate(const struct phase *p, uint32_t tick_hz, double im, double iw)
{
	const struct avrsim_stats *s = &p->st;
	uint32_t period = AVRSIM_F_CPU / tick_hz;

	printf("  control tick, computing          %8.0f cycles mean %8llu worst\n", mean(&s->tick),
	       (unsigned long long)s->tick.max);
	printf("  interrupts per period            %8.0f cycles mean %8.0f worst\n", im, iw);
	printf("  CPU load of a period at %4u Hz   %7.1f %% mean    %7.1f %% worst  (of %u "
	       "cycles; goal at 1 kHz: 40 %% worst)\n",
	       tick_hz, 100.0 * (mean(&s->tick) + im) / period,
	       100.0 * ((double)s->tick.max + iw) / period, period);
	if (tick_hz != 1000)
		printf("  the same at 1 kHz                %7.1f %% mean    %7.1f %% worst\n",
		       100.0 * (mean(&s->tick) + im * 1000.0 / tick_hz) / 16000.0,
		       100.0 * ((double)s->tick.max + iw * 1000.0 / tick_hz) / 16000.0);
}

/* Two rates: the servo (at the slow ticks and at the others), the slow steps, the interrupts, and
 * the load they make together over a slow period of 2^slow_shift ticks: the mean from the means,
 * the worst from each at its worst (a slow tick, the hand-over's tick and the others each at the
 * longest of its kind,
 * the interrupts at their worst rate of cycles, the longest run of the slow steps); then the
 * worst by part, and how far it is from 40 %; the cruder bound of every tick at the servo's worst
 * and every TWI interrupt at the longest of any kind, the same with the busiest period's
 * interrupts in every period, and the loads as measured over one period and one slow period
 * (cycles awake; the busiest of each). */
static void print_two_rates(const struct phase *p, uint32_t tick_hz, uint8_t slow_shift,
			    const struct isr_load *il)
{
	const struct avrsim_stats *s = &p->st;
	uint32_t period = AVRSIM_F_CPU / tick_hz, n = 1u << slow_shift, slow_period = period * n;
	/* the hand-over at a tick of its own, unless it is the slow tick (planner_ticks 2^shift) */
	double servo_ticks_worst =
		(double)s->servo_slow.max +
		(s->servo_handover.n
			 ? (double)s->servo_handover.max + (n - 2u) * (double)s->servo_other.max
			 : (n - 1u) * (double)s->servo_other.max);
	double load_mean = (mean(&s->servo) + il->mean) / period + mean(&s->slow) / slow_period;
	double load_worst = (servo_ticks_worst + n * il->worst + (double)s->slow.max) / slow_period;
	double load_crude = ((double)s->servo.max + il->worst_all_twi) / period +
			    (double)s->slow.max / slow_period;
	double load_busiest = (servo_ticks_worst + (double)s->slow.max) / slow_period +
			      (double)s->isr_sum.max / period;

	printf("  servo tick (TICK high, without the interrupts nested in it)\n"
	       "%35s%8.0f cycles mean %8llu worst\n",
	       "", mean(&s->servo), (unsigned long long)s->servo.max);
	printf("    at a slow tick (the snapshot, new wheel factors)\n"
	       "%35s%8.0f cycles mean %8llu worst\n",
	       "", mean(&s->servo_slow), (unsigned long long)s->servo_slow.max);
	printf("    at the hand-over (the slow steps' results, planner_ticks after the snapshot)\n"
	       "%35s%8.0f cycles mean %8llu worst\n",
	       "", mean(&s->servo_handover), (unsigned long long)s->servo_handover.max);
	printf("    at the other %u ticks of a slow period\n"
	       "%35s%8.0f cycles mean %8llu worst\n",
	       n - 2u, "", mean(&s->servo_other), (unsigned long long)s->servo_other.max);
	printf("  slow steps, a run every %u ticks (SLOW high, without what preempted them)\n"
	       "%35s%8.0f cycles mean %8llu worst  (%llu runs)\n",
	       n, "", mean(&s->slow), (unsigned long long)s->slow.max,
	       (unsigned long long)s->slow.n);
	printf("  interrupts per period (each at its rate, its longest run; the TWI's per kind of "
	       "bus event)\n"
	       "%35s%8.0f cycles mean %8.0f worst\n",
	       "", il->mean, il->worst);
	printf("  interrupts in one period, measured\n"
	       "%35s%8.0f cycles mean %8llu in the busiest\n",
	       "", mean(&s->isr_sum), (unsigned long long)s->isr_sum.max);
	printf("  CPU load at %u Hz over a slow period: (servo x %u + interrupts x %u + slow "
	       "steps) "
	       "/ %u periods (goal: 40 %% worst)\n"
	       "%35s%7.1f %% mean    %7.1f %% worst\n",
	       tick_hz, n, n, n, "", 100.0 * load_mean, 100.0 * load_worst);
	printf("    the worst by part, in %u periods: servo %.0f cycles (%.1f %%), interrupts %.0f "
	       "(%.1f %%; the encoders' %.0f), slow steps %llu (%.1f %%); 40 %% is %u cycles: "
	       "%.0f %s\n",
	       n, servo_ticks_worst, 100.0 * servo_ticks_worst / slow_period, n * il->worst,
	       100.0 * n * il->worst / slow_period, n * il->worst_encoders,
	       (unsigned long long)s->slow.max, 100.0 * (double)s->slow.max / slow_period,
	       slow_period * 2u / 5u, fabs(load_worst * slow_period - slow_period * 0.4),
	       load_worst > 0.4 ? "to go" : "to spare");
	printf("    cruder bounds: every tick at the servo's worst, every TWI interrupt at its "
	       "longest\n"
	       "%35s%25.1f %% worst\n"
	       "%35s%25.1f %% worst with the busiest period's interrupts in every period\n",
	       "", 100.0 * load_crude, "", 100.0 * load_busiest);
	printf("  measured: servo + interrupts in one period\n"
	       "%35s%7.1f %% mean    %7.1f %% in the busiest (of %u cycles)\n",
	       "", 100.0 * mean(&s->fast) / period, 100.0 * (double)s->fast.max / period, period);
	printf("  measured: cycles awake in %u periods (all the work, the main loop's wake-ups "
	       "included)\n"
	       "%35s%7.1f %% mean    %7.1f %% in the busiest (of %u cycles)\n",
	       n, "", 100.0 * mean(&s->window) / slow_period,
	       100.0 * (double)s->window.max / slow_period, slow_period);
}

static void print_phase(const char *title, const struct phase *p, uint32_t tick_hz,
			uint8_t slow_shift)
{
	const struct avrsim_stats *s = &p->st;
	double seconds = (double)p->ticks / tick_hz;
	const struct {
		const char *name;
		uint8_t vec;
	} isr[] = {{"encoder, free wheel left (PCINT2)", m1284p.vec_pcint[2]},
		   {"encoder, free wheel right (PCINT3)", m1284p.vec_pcint[3]},
		   {"encoder, motor left (PCINT0)", m1284p.vec_pcint[0]},
		   {"encoder, motor right (PCINT1)", m1284p.vec_pcint[1]},
		   {"TWI", m1284p.vec_twi},
		   {slow_shift ? "control timer, around the servo" : "control timer",
		    m1284p.vec_timer3_compa}};

	struct isr_load il = isr_load(p);

	printf("\n%s: %llu ticks (%.2f s)\n", title, (unsigned long long)p->ticks, seconds);
	if (slow_shift)
		print_two_rates(p, tick_hz, slow_shift, &il);
	else
		print_one_rate(p, tick_hz, il.mean, il.worst);
	for (size_t i = 0; i < sizeof(isr) / sizeof(isr[0]); i++) {
		const struct avrsim_count *c = &s->isr[isr[i].vec];

		printf("  %-32s %8.0f /s  %4.0f cycles mean %4llu max\n", isr[i].name,
		       (double)c->n / seconds, mean(c), (unsigned long long)c->max);
	}
	printf("  an encoder edge waited for its interrupt %.0f cycles mean, %llu at most\n",
	       mean(&s->edge_wait), (unsigned long long)s->edge_wait.max);
}

static void print_twi(const struct avrsim_stats *s)
{
	static const struct {
		uint8_t status;
		const char *what;
	} ev[] = {{0x60, "own address + write"},    {0x80, "data byte received"},
		  {0xA0, "STOP or repeated start"}, {0xA8, "own address + read"},
		  {0xB8, "data byte sent, ACK"},    {0xC0, "data byte sent, NACK (last)"}};

	printf("\nTWI interrupt per bus event (the 4-cycle response included); SCL held low "
	       "past the master's low half-bit (80 cycles at 100 kHz):\n");
	for (size_t i = 0; i < sizeof(ev) / sizeof(ev[0]); i++) {
		const struct avrsim_count *c = &s->twi[ev[i].status >> 3];
		const struct avrsim_count *k = &s->stretch[ev[i].status >> 3];

		printf("  0x%02X %-28s %6llu events %5.0f cycles mean %5llu max; held %llu times, "
		       "%llu cycles max\n",
		       ev[i].status, ev[i].what, (unsigned long long)c->n, mean(c),
		       (unsigned long long)c->max, (unsigned long long)k->n,
		       (unsigned long long)k->max);
	}
}

int main(int argc, char **argv)
{
	/* The board starts believing (0, -900); the robot is at (-1300, 0): the master says so
	 * (error = estimate - truth), then asks for 1 m/s, 1 m/s^2 and 2.4 m along x. */
	const uint8_t new_pos[] = {PROTO_SET_NEW_POS, 0x05, 0x14, 0xfc, 0x7c, 0, 0};
	const uint8_t set_speed[] = {PROTO_SET_VITESSE_TRAJ, 100, 100};
	const uint8_t go[] = {PROTO_GOTO, 0x04, 0x4c, 0, 0, 0}; /* (1100, 0) */
	struct board_config bc;
	struct sim_config sc;
	struct sim_field f;
	struct avrsim *h;
	struct phase all, cruise;
	struct sim_truth t;
	int profile = 1, realtime = 0;
	int in_cruise = 0, cruised = 0;
	uint32_t flash, ram, tick = 0, mark = 0, poll = 0, next_poll;
	uint64_t ticks0;
	uint8_t rep[7] = {0}, ov[4] = {0}, slow_shift;
	uint16_t at;

	for (int i = 2; i < argc; i++) {
		if (!strcmp(argv[i], "--no-profile"))
			profile = 0;
		else if (!strcmp(argv[i], "--realtime"))
			realtime = 1;
		else
			argc = 0;
	}
	if (argc < 2) {
		fprintf(stderr, "usage: %s asserv_avr.elf [--no-profile] [--realtime]\n", argv[0]);
		return 2;
	}
	avr_robot_config(&bc);
	next_poll = bc.tick_hz / 100u;
	sim_config_defaults(&sc);
	sc.motor.encoder_cpr = 48; /* robot.c */
	sim_field_defaults(&f);
	h = avrsim_open(argv[1], 100000);
	if (!h || avrsim_physics(h, &sc, &f, realtime ? AVRSIM_REALTIME : AVRSIM_EXACT))
		return 1;
	if (avrsim_run_to_tick_end(h) || avrsim_i2c_write(h, new_pos, 7, 1) ||
	    avrsim_run_to_tick_end(h) || avrsim_i2c_write(h, set_speed, 3, 1) ||
	    avrsim_run_to_tick_end(h) || avrsim_i2c_write(h, go, 6, 1))
		return 1;
	memset(&all, 0, sizeof(all));
	memset(&cruise, 0, sizeof(cruise));
	all.st.sp_min = 0xFFFF;
	avrsim_stats_reset(h);
	avrsim_profile(h, profile, 1);
	ticks0 = avrsim_ticks(h);
	for (;;) {
		if (avrsim_run_to_tick_end(h))
			return 1;
		/* The ticks the binary ran: with two rates a transaction can span a compare match.
		 */
		tick = (uint32_t)(avrsim_ticks(h) - ticks0);
		sim_get_truth(avrsim_sim(h), &t);
		if (!in_cruise && !cruised && t.v_mm_s >= CRUISE_MM_S) {
			in_cruise = 1;
			merge(&all, avrsim_stats(h), tick - mark);
			mark = tick;
			avrsim_stats_reset(h);
		} else if (in_cruise && t.v_mm_s < CRUISE_END_MM_S) {
			in_cruise = 0;
			cruised = 1;
			merge(&cruise, avrsim_stats(h), tick - mark);
			merge(&all, avrsim_stats(h), tick - mark);
			mark = tick;
			avrsim_stats_reset(h);
		}
		if (tick >= next_poll) { /* the master, every 10 ms */
			next_poll += bc.tick_hz / 100u;
			poll++;
			if (avrsim_i2c_read(h, rep, 1))
				return 1;
			if (!(rep[0] & STATUS_BUSY_TRAJET))
				break;
			if (poll % 2 == 0 &&
			    (avrsim_i2c_write(h, (const uint8_t[]){PROTO_POSITION}, 1, 0) ||
			     avrsim_i2c_read(h, rep + 1, 6)))
				return 1;
		}
		if (tick > 10u * bc.tick_hz)
			break;
	}
	merge(&all, avrsim_stats(h), tick - mark);
	avrsim_sizes(h, &flash, &ram);
	slow_shift = avrsim_slow_shift(h);

	printf("asserv_avr.elf on an ATmega1284P at 16 MHz: control at %u Hz, free wheels %u "
	       "counts/turn, motor encoders %u counts/motor turn\n",
	       bc.tick_hz, (unsigned)sc.enc_cpr, (unsigned)sc.motor.encoder_cpr);
	if (realtime)
		printf("real-time lockstep: the physics follows the cycles, the tick's included\n");
	if (slow_shift)
		printf("two rates: the servo at %u Hz in the control timer's interrupt, the slow "
		       "steps at %u Hz in the main loop (slow_shift %u)\n",
		       bc.tick_hz, bc.tick_hz >> slow_shift, slow_shift);
	printf("flash %u bytes (.text + .data); RAM %u bytes static (.data + .bss + .noinit) + %u "
	       "bytes of stack at most = %u of 16384\n",
	       flash, ram, (unsigned)(m1284p.ramend - all.st.sp_min),
	       (unsigned)(ram + m1284p.ramend - all.st.sp_min));
	print_phase("the whole move", &all, bc.tick_hz, slow_shift);
	if (cruised)
		print_phase("at 1 m/s (true speed from 0.95 m/s up to below 0.9 m/s)", &cruise,
			    bc.tick_hz, slow_shift);
	else
		printf("\nthe robot never reached 0.95 m/s\n");
	print_twi(&all.st);
	if (profile) {
		printf("\nThe %s's cycles by function, mean per tick over the move (inclusive: "
		       "with what it calls):\n",
		       slow_shift ? "servo tick" : "tick");
		avrsim_profile_report(h, stdout, AVRSIM_PART_TICK, 20, all.st.tick.n, 0);
		printf("\nThe same in the longest tick (%llu cycles):\n",
		       (unsigned long long)all.st.tick.max);
		avrsim_profile_report(h, stdout, AVRSIM_PART_TICK, 16, 1, 1);
	}
	if (profile && slow_shift) {
		printf("\nThe slow steps' cycles by function, mean per run over the move "
		       "(inclusive):\n");
		avrsim_profile_report(h, stdout, AVRSIM_PART_SLOW, 20, all.st.slow.n, 0);
		printf("\nThe same in the longest run (%llu cycles):\n",
		       (unsigned long long)all.st.slow.max);
		avrsim_profile_report(h, stdout, AVRSIM_PART_SLOW, 16, 1, 1);
	}
	avrsim_peek(h, (uint16_t)(avrsim_board(h) + avrsim_layout(h)->slow_overruns), ov, 2);
	if (avrsim_symbol(h, "avr_tick_overruns", &at) == 0)
		avrsim_peek(h, at, ov + 2, 2);
	printf("\noverruns: slow steps not done by their hand-over (slow_overruns) %u, control "
	       "periods lost (avr_tick_overruns) %u\n",
	       ov[0] | ov[1] << 8, ov[2] | ov[3] << 8);
	sim_get_truth(avrsim_sim(h), &t);
	printf("\nend after %u ticks: status 0x%02x, last POSITION (%d, %d) mm, truth (%.1f, "
	       "%.1f) mm\n",
	       tick, rep[0], (int16_t)(uint16_t)(rep[1] << 8 | rep[2]),
	       (int16_t)(uint16_t)(rep[3] << 8 | rep[4]), t.odo_pose.x_mm, t.odo_pose.y_mm);
	avrsim_close(h);
	return 0;
}
