/* The simavr harness (avrsim.h): simavr 1.6 runs the binary one instruction at a time; between
 * two instructions the harness delivers what is due: encoder edges and sensor levels (a queue
 * ordered by cycle), a physics substep, an I2C bus event. */
#define _POSIX_C_SOURCE 200809L /* strdup, open */
#include "avrsim.h"

#include <fcntl.h>
#include <gelf.h>
#include <libelf.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include <sim_avr.h>
#include <sim_elf.h>
#include <sim_core.h>
#include <sim_cycle_timers.h>
#include <sim_interrupts.h>
#include <sim_io.h>
#include <sim_irq.h>
#include <avr_adc.h>
#include <avr_eeprom.h>
#include <avr_extint.h>
#include <avr_ioport.h>

#include "avr_units.h"
#include "m1284p.h"
#include "pinmap.h"
#include "protocol_defs.h"

#define EXACT_GUARD 1000u   /* cycles between the last edge of a period and its compare match */
#define ISR_RESPONSE 4u     /* cycles simavr does not charge for taking an interrupt */
#define I2C_TIMEOUT 800000u /* cycles (50 ms) a transaction may take */
#define MAX_FRAMES 64
#define SYNTH_SUBSTEP 1600u /* cycles: 100 us */

/* TWSR status codes the harness produces (the slave's side of the ATmega's TWI). */
enum {
	TW_SR_SLA_ACK = 0x60,
	TW_SR_DATA_ACK = 0x80,
	TW_SR_DATA_NACK = 0x88,
	TW_SR_STOP = 0xA0,
	TW_ST_SLA_ACK = 0xA8,
	TW_ST_DATA_ACK = 0xB8,
	TW_ST_DATA_NACK = 0xC0,
};

struct event {
	uint64_t cycle;
	uint64_t seq; /* ties keep the order of scheduling */
	avr_irq_t *irq;
	uint32_t value;
	int8_t port; /* a pin of port A..D (0..3), or -1 */
	uint8_t bit;
	int8_t enc;    /* an encoder edge (0..3, as enc_count[]), or -1 */
	int64_t count; /* its count once delivered */
};

/* I2C master operations. */
enum { OP_START, OP_ADDR, OP_TX, OP_RX, OP_STOP };

struct op {
	uint8_t kind;
	uint8_t byte; /* OP_ADDR, OP_TX: sent; OP_RX: 1 = ACK, 0 = NACK */
};

/* Per part (enum avrsim_part). */
struct func {
	uint32_t addr, size; /* bytes in flash */
	char *name;
	uint64_t self[2], incl[2];             /* since avrsim_profile() */
	uint64_t self_now[2], incl_now[2];     /* in the run in progress */
	uint64_t self_worst[2], incl_worst[2]; /* in the longest run */
	uint32_t stamp;   /* the instruction that last counted it inclusive (recursion) */
	uint8_t no_frame; /* a jump table dispatcher: it jumps on, it never returns */
};

struct frame {
	uint16_t func;
	uint16_t sp;
	uint8_t isr_base; /* the first frame of an interrupt: inclusive counts stop here */
};

struct avrsim {
	avr_t *avr;
	char *elf_path; /* for avrsim_power_cycle() */
	uint32_t i2c_hz;
	elf_firmware_t fw;
	uint32_t text_size, data_size, bss_size;
	uint16_t board_addr;
	struct avr_layout layout;
	avr_int_vector_t *twi_vec;

	/* pins */
	avr_ioport_t *port[4]; /* A..D */
	avr_irq_t *pin[4][8];
	avr_irq_t *adc[2];
	uint8_t pin_level[4][8]; /* last level scheduled */
	uint32_t adc_mv[2];

	/* event queue (binary heap) */
	struct event *q;
	uint32_t nq, capq;
	uint64_t seq;
	uint64_t wake_armed; /* cycle of the simavr timer that bounds a sleep, 0 if none */

	/* control period */
	uint8_t tick_pin;
	uint8_t tick_depth; /* interrupts running when TICK rose: 0 (one rate) or 1 (two) */
	uint64_t tick_rise;
	uint64_t ticks;
	uint64_t servo_now; /* the tick's cycles so far, the interrupts in it excluded */
	uint64_t last_compare, compares, period_cycles;
	uint64_t period_idle, period_resp, period_isr, period_servo;
	uint64_t awake[8]; /* the last control periods' cycles awake, by compares % 8 */
	/* the slow steps (two rates) */
	uint8_t slow_pin;
	uint8_t slow_shift;
	uint64_t slow_now;      /* this run's cycles so far, preemptions excluded */
	uint64_t slows;         /* runs ended */
	uint64_t next_compare;  /* exact mode: predicted when the timer restarts */
	uint8_t freeze_pending; /* exact mode: stop the control timer once this instruction is done
				 */
	uint8_t tccr3b;         /* its clock selection while stopped */
	/* exact mode, avrsim_master_hold(): the control timer's interrupt is held (masked) while
	 * the master acts; a compare match meanwhile is raised again when the hold ends */
	uint8_t hold, hold_ocie, compare_held, releasing;
	avr_int_vector_t *t3_vec;

	/* physics */
	enum avrsim_lockstep mode;
	struct sim *sim;
	uint64_t phys_next;          /* cycle of the next substep boundary, UINT64_MAX if none */
	uint64_t win_start, win_len; /* exact mode: this period's window */
	uint32_t sub;                /* substeps done in the window */
	uint32_t substeps;           /* per control period */
	uint16_t tick_hz;            /* the board's, read at its first tick */
	int64_t enc_count[4];        /* free left, free right, motor left, motor right: scheduled */
	int64_t enc_delivered[4];    /* the same, delivered to the pins */
	double synth_rate[4];        /* synthetic edges without physics [counts/s] */
	double synth_pos[4];
	/* The first edge its interrupt has not yet taken, per encoder (each has its pin-change
	 * interrupt) (0: none) [cycle]. */
	uint64_t edge_at[4];
	char error[160];

	/* I2C master */
	uint32_t bit; /* SCL period [cycles] */
	struct op ops[48];
	uint8_t nops, opi;
	uint8_t op_begun;
	uint64_t twi_next;    /* cycle of the next bus step, UINT64_MAX while none or held */
	uint64_t op_end;      /* cycle the current byte ended */
	uint8_t wait_release; /* TWINT set by the harness, not yet cleared by the firmware */
	uint8_t wait_status;  /* the status it was set with */
	uint8_t held;         /* the last write ended without STOP: the bus is ours */
	uint8_t address;      /* 7-bit address the master talks to */
	uint8_t addressed;    /* the slave: 'W' receiving, 'R' transmitting, 0 not addressed */
	uint8_t nack;         /* the transaction failed */
	uint8_t tx_latch;     /* TWDR when the firmware released after a transmit status */
	uint8_t *rx_out;      /* where OP_RX bytes go */
	uint8_t rx_n;
	uint64_t bus_free_at;
	uint8_t twi_status_in_isr; /* status when the running TWI interrupt started */
	uint64_t isr_own[64];      /* per nesting level: the cycles of the interrupt running there,
				    * without those nested in it */

	/* profile */
	int profiling, profile_tick_only;
	struct func *funcs;
	uint32_t nfuncs;
	struct {
		char *name;
		uint16_t addr;
	} * objs; /* RAM objects */
	uint32_t nobjs;
	uint16_t *func_of_word; /* flash word -> function index + 1, 0 = none */
	uint64_t worst_len[2];  /* the longest run profiled, per part */
	struct frame frames[MAX_FRAMES];
	uint32_t nframes;
	uint32_t stamp;
	uint8_t isr_entered; /* the next function entered is an interrupt's */

	struct avrsim_stats st;
};

static const char port_name[4] = {'A', 'B', 'C', 'D'};

/* ---------------------------------------------------------------------------------------------
 * Event queue
 */

static int ev_before(const struct event *a, const struct event *b)
{
	return a->cycle < b->cycle || (a->cycle == b->cycle && a->seq < b->seq);
}

static void ev_push(struct avrsim *h, uint64_t cycle, avr_irq_t *irq, uint32_t value, int port,
		    int bit, int enc, int64_t count)
{
	uint32_t i;

	if (h->nq == h->capq) {
		h->capq = h->capq ? 2 * h->capq : 256;
		h->q = realloc(h->q, h->capq * sizeof(*h->q));
		if (!h->q)
			abort();
	}
	i = h->nq++;
	h->q[i] = (struct event){cycle,        h->seq++,     irq,         value,
				 (int8_t)port, (uint8_t)bit, (int8_t)enc, count};
	while (i > 0 && ev_before(&h->q[i], &h->q[(i - 1) / 2])) {
		struct event t = h->q[i];

		h->q[i] = h->q[(i - 1) / 2];
		h->q[(i - 1) / 2] = t;
		i = (i - 1) / 2;
	}
}

static struct event ev_pop(struct avrsim *h)
{
	struct event top = h->q[0];
	uint32_t i = 0;

	h->q[0] = h->q[--h->nq];
	for (;;) {
		uint32_t l = 2 * i + 1, r = l + 1, m = i;

		if (l < h->nq && ev_before(&h->q[l], &h->q[m]))
			m = l;
		if (r < h->nq && ev_before(&h->q[r], &h->q[m]))
			m = r;
		if (m == i)
			break;
		struct event t = h->q[i];

		h->q[i] = h->q[m];
		h->q[m] = t;
		i = m;
	}
	return top;
}

/* A pin level (port 0..3 for A..D) from the given cycle on; nothing if it is already so. An
 * encoder's pin gives its encoder and the count the change makes (else enc is -1). */
static void set_pin_enc(struct avrsim *h, int port, int bit, uint8_t level, uint64_t cycle, int enc,
			int64_t count)
{
	if (h->pin_level[port][bit] == level)
		return;
	h->pin_level[port][bit] = level;
	ev_push(h, cycle, h->pin[port][bit], level, port, bit, enc, count);
}

static void set_pin(struct avrsim *h, int port, int bit, uint8_t level, uint64_t cycle)
{
	set_pin_enc(h, port, bit, level, cycle, -1, 0);
}

static void set_adc(struct avrsim *h, int ch, uint32_t mv, uint64_t cycle)
{
	if (h->adc_mv[ch] == mv)
		return;
	h->adc_mv[ch] = mv;
	ev_push(h, cycle, h->adc[ch], mv, -1, 0, -1, 0);
}

/* Drives a pin or an analog input now. A driven pin is also the port's "external" level, which
 * simavr gives the pin again whenever the firmware writes the port register (else an input's
 * pull-up would win over the harness). */
static void deliver(struct avrsim *h, const struct event *e)
{
	if (e->port >= 0) {
		avr_ioport_t *p = h->port[e->port];
		uint8_t m = (uint8_t)(1u << e->bit);

		p->external.pull_value = (uint8_t)(e->value ? p->external.pull_value | m
							    : p->external.pull_value & ~m);
	}
	if (e->enc >= 0) {
		h->enc_delivered[e->enc] = e->count;
		if (!h->edge_at[e->enc])
			h->edge_at[e->enc] = h->avr->cycle;
	}
	avr_raise_irq(e->irq, e->value);
}

/* ---------------------------------------------------------------------------------------------
 * Registers and memory
 */

static uint8_t reg(const struct avrsim *h, uint16_t addr)
{
	return h->avr->data[addr];
}

void avrsim_peek(const struct avrsim *h, uint16_t addr, void *buf, uint16_t n)
{
	memcpy(buf, &h->avr->data[addr], n);
}

void avrsim_poke(struct avrsim *h, uint16_t addr, const void *buf, uint16_t n)
{
	memcpy(&h->avr->data[addr], buf, n);
}

int16_t avrsim_duty_q15(uint16_t counts, int backward)
{
	int32_t q = (int32_t)(((uint32_t)counts * 32767u + AVR_PWM_TOP / 2u) / AVR_PWM_TOP);

	if (q > 32767)
		q = 32767;
	return (int16_t)(backward ? -q : q);
}

static void read_duties(const struct avrsim *h, int16_t *left, int16_t *right)
{
	uint16_t a = (uint16_t)(reg(h, m1284p.ocr1a) | reg(h, m1284p.ocr1a + 1u) << 8);
	uint16_t b = (uint16_t)(reg(h, m1284p.ocr1b) | reg(h, m1284p.ocr1b + 1u) << 8);
	uint8_t d = reg(h, m1284p.portc);

	*left = avrsim_duty_q15(a, (d >> PIN_DIR_LEFT_BIT) & 1u);
	*right = avrsim_duty_q15(b, (d >> PIN_DIR_RIGHT_BIT) & 1u);
}

static uint16_t flash_u16(const struct avrsim *h, uint32_t addr)
{
	return (uint16_t)(h->avr->flash[addr] | h->avr->flash[addr + 1] << 8);
}

/* A register write as the firmware's would be: through simavr's handler for it, if any. */
static void io_write(struct avrsim *h, uint16_t addr, uint8_t v)
{
	avr_t *avr = h->avr;
	avr_io_write_t w = avr->io[AVR_DATA_TO_IO(addr)].w.c;

	if (w)
		w(avr, addr, v, avr->io[AVR_DATA_TO_IO(addr)].w.param);
	else
		avr->data[addr] = v;
}

static uint8_t io_read(struct avrsim *h, uint16_t addr)
{
	avr_t *avr = h->avr;
	avr_io_read_t r = avr->io[AVR_DATA_TO_IO(addr)].r.c;

	return r ? r(avr, addr, avr->io[AVR_DATA_TO_IO(addr)].r.param) : avr->data[addr];
}

/* Exact mode: the control timer stands still while the tick runs, so that the tick takes no
 * time for the firmware either (its compare matches stay one period of the physics apart, the
 * tick's cost whatever it is). */
static void timer_stop(struct avrsim *h)
{
	h->tccr3b = reg(h, m1284p.tccr3b);
	io_write(h, m1284p.tccr3b, (uint8_t)(h->tccr3b & ~7u));
}

static void timer_restart(struct avrsim *h)
{
	uint16_t tcnt, ocr;

	io_write(h, m1284p.tccr3b, h->tccr3b);
	tcnt = (uint16_t)(io_read(h, m1284p.tcnt3) | io_read(h, m1284p.tcnt3 + 1u) << 8);
	ocr = (uint16_t)(reg(h, m1284p.ocr3a) | reg(h, m1284p.ocr3a + 1u) << 8);
	h->next_compare = h->avr->cycle + (uint64_t)(ocr + 1u - tcnt) * 8u; /* prescaler 8 */
}

/* ---------------------------------------------------------------------------------------------
 * Physics
 */

/* Quadrature levels of a count: A leads B going forward (pinmap.h). */
static uint8_t quad_a(int64_t n)
{
	uint8_t ph = (uint8_t)((uint64_t)n & 3u);

	return ph == 1 || ph == 2;
}

static uint8_t quad_b(int64_t n)
{
	return ((uint64_t)n & 3u) >= 2;
}

/* Encoder e's pins (pinmap.h): free left PC2/PC3, free right PD6/PD7, motor left PA2/PA3, motor
 * right PB2/PB3. */
static void enc_pins(int e, int *port, int *bit_a)
{
	static const int8_t port_of[4] = {2, 3, 0, 1}, bit_of[4] = {2, 6, 2, 2};

	*port = port_of[e];
	*bit_a = bit_of[e];
}

/* The edges of encoder e as its continuous position goes from p0 to p1 over [c0, c0 + len)
 * and its count from n0 to n1 (the floors): one edge per count, at the cycle where the linear
 * interpolation crosses it. */
static void schedule_edges(struct avrsim *h, int e, double p0, double p1, int64_t n0, int64_t n1,
			   uint64_t c0, uint64_t len)
{
	int port, bit_a;
	int64_t n = n0;

	enc_pins(e, &port, &bit_a);
	while (n != n1) {
		int64_t next = n1 > n ? n + 1 : n - 1;
		double boundary = (double)(n1 > n ? next : n); /* the integer crossed */
		double f = p1 != p0 ? (boundary - p0) / (p1 - p0) : 1.0;
		uint64_t at;

		if (!(f >= 0.0))
			f = 0.0;
		if (f > 1.0)
			f = 1.0;
		at = c0 + (uint64_t)(f * (double)(len - 1u));
		set_pin_enc(h, port, bit_a, quad_a(next), at, e, next);
		set_pin_enc(h, port, bit_a + 1, quad_b(next), at, e, next);
		h->st.edges++;
		n = next;
	}
}

static void schedule_sensors(struct avrsim *h, const struct sim_sensors *s, uint64_t at)
{
	static const int line_port[4] = {0, 0, 2, 2}, line_bit[4] = {6, 7, 6, 7};
	/* CAPTEUR_n on PBn, but CAPTEUR_2 and CAPTEUR_3 on PA4 and PA5 */
	static const int shock_port[8] = {1, 1, 0, 0, 1, 1, 1, 1};
	static const int shock_bit[8] = {0, 1, 4, 5, 4, 5, 6, 7};

	for (int i = 0; i < 8; i++)
		set_pin(h, shock_port[i], shock_bit[i], !((s->shock_mask >> i) & 1u), at);
	set_pin(h, 3, PIN_BASKET_BIT, !s->basket, at);
	for (int i = 0; i < 4; i++)
		set_pin(h, line_port[i], line_bit[i], !((s->line_mask >> i) & 1u), at);
	for (int ch = 0; ch < 2; ch++) {
		double mv =
			AVR_CURRENT_ZERO_MV + s->current_mA[ch] * (AVR_CURRENT_MV_PER_A / 1000.0);

		mv = mv < 0.0 ? 0.0 : mv > AVR_ADC_VREF_MV ? AVR_ADC_VREF_MV : mv;
		set_adc(h, ch, (uint32_t)lround(mv), at);
	}
}

/* One substep over [c0, c0 + len). */
static void substep(struct avrsim *h, uint64_t c0, uint64_t len, int set_duty)
{
	struct sim *s = h->sim;
	struct sim_sensors after;
	double p0[4] = {s->enc_pos[0], s->enc_pos[1], s->motor_pos[0], s->motor_pos[1]};
	double p1[4];
	int64_t n1[4];

	if (set_duty) {
		int16_t l, r;

		read_duties(h, &l, &r);
		sim_set_duty(s, l, r);
	}
	sim_step(s);
	sim_read_sensors(s, &after);
	p1[0] = s->enc_pos[0];
	p1[1] = s->enc_pos[1];
	p1[2] = s->motor_pos[0];
	p1[3] = s->motor_pos[1];
	n1[0] = after.enc_total[0];
	n1[1] = after.enc_total[1];
	n1[2] = after.motor_total[0];
	n1[3] = after.motor_total[1];
	for (int e = 0; e < 4; e++) {
		schedule_edges(h, e, p0[e], p1[e], h->enc_count[e], n1[e], c0, len);
		h->enc_count[e] = n1[e];
	}
	schedule_sensors(h, &after, c0 + len - 1u);
}

/* Without physics: the encoders turn at constant rates over [c0, c0 + len). */
static void synthetic_substep(struct avrsim *h, uint64_t c0, uint64_t len)
{
	for (int e = 0; e < 4; e++) {
		double p0 = h->synth_pos[e];
		double p1 = p0 + h->synth_rate[e] * (double)len / AVRSIM_F_CPU;
		int64_t n1 = (int64_t)floor(p1);

		schedule_edges(h, e, p0, p1, h->enc_count[e], n1, c0, len);
		h->enc_count[e] = n1;
		h->synth_pos[e] = p1;
	}
}

static void physics_boundary(struct avrsim *h)
{
	if (!h->sim) {
		synthetic_substep(h, h->phys_next, SYNTH_SUBSTEP);
		h->phys_next += SYNTH_SUBSTEP;
		return;
	}
	if (h->mode == AVRSIM_REALTIME) {
		uint64_t len = (uint64_t)h->sim->cfg.substep_ns * AVRSIM_F_CPU / 1000000000u;

		substep(h, h->phys_next, len, 1);
		h->phys_next += len;
		return;
	}
	/* exact: substep sub of this period's window */
	uint64_t a = h->win_start + h->win_len * h->sub / h->substeps;
	uint64_t b = h->win_start + h->win_len * (h->sub + 1u) / h->substeps;

	substep(h, a, b - a, h->sub == 0);
	h->sub++;
	h->phys_next = h->sub < h->substeps ? b : UINT64_MAX;
}

static void fail(struct avrsim *h, const char *msg)
{
	if (!h->error[0])
		snprintf(h->error, sizeof(h->error), "%s (cycle %llu)", msg,
			 (unsigned long long)h->avr->cycle);
}

static void add_count(struct avrsim_count *c, uint64_t cycles)
{
	c->n++;
	c->cycles += cycles;
	if (cycles > c->max)
		c->max = cycles;
}

/* The control timer's compare match. */
static void on_compare(struct avr_irq_t *irq, uint32_t value, void *param)
{
	struct avrsim *h = param;
	uint64_t now = h->avr->cycle;

	(void)irq;
	if (!value || h->releasing)
		return; /* cleared, or a held compare match raised again: counted when it came */
	if (h->compares) {
		uint64_t awake = now - h->last_compare - h->period_idle + h->period_resp;
		uint32_t w = 1u << h->slow_shift;

		add_count(&h->st.period, awake);
		add_count(&h->st.isr_sum, h->period_isr);
		add_count(&h->st.fast, h->period_servo + h->period_isr);
		h->awake[h->compares % 8u] = awake;
		if (h->compares >= w) {
			uint64_t sum = 0;

			for (uint32_t i = 0; i < w; i++)
				sum += h->awake[(h->compares - i) % 8u];
			add_count(&h->st.window, sum);
		}
	}
	h->period_idle = h->period_resp = h->period_isr = h->period_servo = 0;
	h->last_compare = now;
	h->compares++;
	if (h->mode == AVRSIM_REALTIME && h->phys_next == UINT64_MAX)
		h->phys_next = now; /* the physics starts with the first period */
	if (h->mode == AVRSIM_EXACT) {
		if (h->ticks > 0 && h->sub < h->substeps)
			fail(h, "exact lockstep: the period's physics did not finish before its "
				"compare match");
		h->freeze_pending = 1;
		if (h->hold && h->hold_ocie) {
			h->compare_held = 1;
			h->st.compares_held++;
		}
	}
}

/* 1 if the tick that just ended was a slow tick (two rates: the one that hands over and takes
 * the snapshot, board.h), from the board's tick counter. */
static int slow_tick_ended(struct avrsim *h)
{
	uint16_t tick;

	if (!h->slow_shift)
		return 0;
	avrsim_peek(h, (uint16_t)(h->board_addr + h->layout.tick), &tick, 2);
	return (((uint16_t)(tick - 1u)) & ((1u << h->slow_shift) - 1u)) == 0;
}

/* The tick that just ended took the slow steps' results (planner_ticks after its snapshot). */
static int handover_tick_ended(struct avrsim *h)
{
	uint8_t since, planner;

	if (!h->slow_shift)
		return 0;
	avrsim_peek(h, (uint16_t)(h->board_addr + h->layout.since_snapshot), &since, 1);
	avrsim_peek(h, (uint16_t)(h->board_addr + h->layout.planner_ticks), &planner, 1);
	return since == planner;
}

static void on_tick_end(struct avrsim *h)
{
	uint64_t now = h->avr->cycle, end;

	if (!h->tick_hz) {
		avrsim_peek(h, (uint16_t)(h->board_addr + h->layout.tick_hz), &h->tick_hz, 2);
		avrsim_peek(h, (uint16_t)(h->board_addr + h->layout.slow_shift), &h->slow_shift, 1);
		h->period_cycles = AVRSIM_F_CPU / h->tick_hz;
		if (h->sim) {
			uint64_t ns = 1000000000u / h->tick_hz;

			h->substeps = (uint32_t)(ns / h->sim->cfg.substep_ns);
			if (ns % h->sim->cfg.substep_ns)
				fail(h, "the control period is not a whole number of substeps");
		}
	}
	if (h->mode != AVRSIM_EXACT)
		return;
	if (h->compares != h->ticks) {
		fail(h, "exact lockstep: a control period was overrun");
		return;
	}
	timer_restart(h);
	end = h->next_compare - EXACT_GUARD;
	if (end < now + 10u * h->substeps) {
		fail(h, "exact lockstep: the tick ran past its period");
		return;
	}
	h->win_start = now;
	h->win_len = end - now;
	h->sub = 0;
	h->phys_next = now;
}

/* ---------------------------------------------------------------------------------------------
 * I2C master, and the slave side of the TWI that simavr 1.6 gets wrong
 */

static void twi_raise(struct avrsim *h, uint8_t status)
{
	avr_t *avr = h->avr;

	avr->data[m1284p.twsr] = (uint8_t)((avr->data[m1284p.twsr] & 0x07u) | status);
	h->wait_release = 1;
	h->wait_status = status;
	h->twi_next = UINT64_MAX;
	avr_raise_interrupt(avr, h->twi_vec); /* sets TWINT */
}

/* The firmware wrote TWCR. TWINT is cleared by writing it 1; TWSTO clears itself in slave
 * mode. */
static void twcr_write(struct avr_t *avr, avr_io_addr_t addr, uint8_t v, void *param)
{
	struct avrsim *h = param;
	uint8_t twint = (uint8_t)(1u << m1284p.twint);
	uint8_t old = avr->data[addr];
	uint8_t nv = (uint8_t)(v & ~twint & ~(1u << m1284p.twsto));

	if ((v & twint) && (old & twint)) {
		avr_clear_interrupt(avr, h->twi_vec);
		if (h->wait_release) {
			uint64_t due = h->op_end + h->bit / 2u;

			h->wait_release = 0;
			if (h->wait_status == TW_ST_SLA_ACK || h->wait_status == TW_ST_DATA_ACK)
				h->tx_latch = avr->data[m1284p.twdr];
			/* A STOP's status holds no clock: nothing waits on it but the next START.
			 */
			if (h->wait_status != TW_SR_STOP || h->ops[h->opi].kind != OP_STOP) {
				struct avrsim_count *s = &h->st.stretch[h->wait_status >> 3];

				if (avr->cycle > due) {
					s->n++;
					s->cycles += avr->cycle - due;
					if (avr->cycle - due > s->max)
						s->max = avr->cycle - due;
				}
			}
			h->opi++;
			h->op_begun = 0;
			h->twi_next = avr->cycle > due ? avr->cycle : due;
			if (h->opi >= h->nops)
				h->twi_next = UINT64_MAX;
		}
	} else {
		nv |= (uint8_t)(old & twint);
	}
	avr->data[addr] = nv;
}

static uint8_t slave_acks(const struct avrsim *h, uint8_t addr_byte)
{
	uint8_t twcr = reg(h, m1284p.twcr);

	return (twcr & (1u << m1284p.twen)) && (twcr & (1u << m1284p.twea)) &&
	       !(twcr & (1u << m1284p.twint)) && (reg(h, m1284p.twar) >> 1) == (addr_byte >> 1);
}

static void set_bus_pins(struct avrsim *h, uint8_t scl, uint8_t sda)
{
	set_pin(h, 2, 0, scl, h->avr->cycle);
	set_pin(h, 2, 1, sda, h->avr->cycle);
}

/* The next bus step of the transaction in progress: an operation begins, or the one begun
 * ends (its byte or condition is complete on the bus). */
static void twi_bus_event(struct avrsim *h)
{
	uint64_t now = h->avr->cycle;
	struct op *op = &h->ops[h->opi];

	h->twi_next = UINT64_MAX;
	if (!h->op_begun) {
		h->op_begun = 1;
		switch (op->kind) {
		case OP_START:
		case OP_STOP:
			h->twi_next = now + h->bit / 2u;
			break;
		default:
			h->twi_next = now + 9u * h->bit;
			h->st.twi_bytes++;
			break;
		}
		if (op->kind == OP_START && h->addressed == 'W') {
			/* A repeated start while addressed as a receiver: the TWI reports it at
			 * once and holds SCL low until it is served. */
			set_bus_pins(h, 0, 0);
			h->op_end = now;
			h->addressed = 0;
			twi_raise(h, TW_SR_STOP);
		} else if (op->kind == OP_START) {
			set_bus_pins(h, 0, 0);
		}
		return;
	}
	h->op_end = now;
	switch (op->kind) {
	case OP_START:
		break;
	case OP_ADDR:
		if (!slave_acks(h, op->byte)) {
			h->nack = 1;
			break;
		}
		h->addressed = (op->byte & 1u) ? 'R' : 'W';
		twi_raise(h, (op->byte & 1u) ? TW_ST_SLA_ACK : TW_SR_SLA_ACK);
		return;
	case OP_TX:
		if (!(reg(h, m1284p.twcr) & (1u << m1284p.twea))) {
			h->nack = 1;
			break;
		}
		h->avr->data[m1284p.twdr] = op->byte;
		twi_raise(h, TW_SR_DATA_ACK);
		return;
	case OP_RX:
		if (h->rx_out && h->rx_n) {
			*h->rx_out++ = h->tx_latch;
			h->rx_n--;
		}
		if (!op->byte)
			h->addressed = 0; /* NACK: the TWI leaves the addressed state */
		twi_raise(h, op->byte ? TW_ST_DATA_ACK : TW_ST_DATA_NACK);
		return;
	case OP_STOP:
		set_bus_pins(h, 1, 1);
		h->held = 0;
		h->bus_free_at = now + h->bit / 2u;
		if (h->addressed == 'W') {
			h->addressed = 0;
			twi_raise(h, TW_SR_STOP);
			return;
		}
		h->addressed = 0;
		break;
	}
	if (h->nack == 1) { /* the master gives up: STOP */
		h->nack = 2;
		h->ops[0] = (struct op){OP_STOP, 0};
		h->nops = 1;
		h->opi = 0;
		h->op_begun = 0;
		h->twi_next = now + h->bit / 2u;
		return;
	}
	h->opi++;
	h->op_begun = 0;
	h->twi_next = h->opi < h->nops ? now : UINT64_MAX;
}

/* ---------------------------------------------------------------------------------------------
 * Running
 */

/* The timer that bounds a sleeping core. simavr lets a sleeping core jump to its next cycle
 * timer within one avr_run(), past a timer that fires and is done: so this one re-arms itself one
 * cycle on until the harness has dealt with what is due (arm_wake() then moves it). */
static avr_cycle_count_t wake(struct avr_t *avr, avr_cycle_count_t when, void *param)
{
	struct avrsim *h = param;

	(void)avr;
	h->wake_armed = when + 1u;
	return when + 1u;
}

/* Makes a sleeping core stop at the next cycle something is due. */
static void arm_wake(struct avrsim *h)
{
	uint64_t next = h->phys_next;

	if (h->nq && h->q[0].cycle < next)
		next = h->q[0].cycle;
	if (h->twi_next < next)
		next = h->twi_next;
	if (next == h->wake_armed)
		return;
	if (h->wake_armed)
		avr_cycle_timer_cancel(h->avr, wake, h);
	h->wake_armed = 0;
	if (next == UINT64_MAX)
		return;
	h->wake_armed = next > h->avr->cycle ? next : h->avr->cycle + 1u;
	avr_cycle_timer_register(h->avr, h->wake_armed - h->avr->cycle, wake, h);
}

/* The instruction that ran from pc0 for d cycles, in the part that was running (the pins'
 * levels before it: the tick's rising edge is not the tick's, its falling edge is). */
static void profile_step(struct avrsim *h, uint32_t pc0, uint64_t d, int isr_entry, int isr_return)
{
	avr_t *avr = h->avr;
	uint16_t sp = _avr_sp_get(avr);
	uint32_t f0 = h->func_of_word[(pc0 >> 1) & 0xFFFFu];
	uint32_t f1 = h->func_of_word[(avr->pc >> 1) & 0xFFFFu];
	int part = h->tick_pin            ? AVRSIM_PART_TICK
		   : h->slow_pin          ? AVRSIM_PART_SLOW
		   : h->profile_tick_only ? -1
					  : AVRSIM_PART_TICK;

	if (part >= 0) {
		if (f0)
			h->funcs[f0 - 1].self_now[part] += d;
		h->stamp++;
		for (uint32_t i = h->nframes; i-- > 0;) {
			struct func *f = &h->funcs[h->frames[i].func];

			if (f->stamp != h->stamp) {
				f->stamp = h->stamp;
				f->incl_now[part] += d;
			}
			if (h->frames[i].isr_base)
				break;
		}
	}
	while (h->nframes && sp > h->frames[h->nframes - 1].sp)
		h->nframes--;
	if (isr_entry)
		h->isr_entered = 1;
	if (isr_return)
		h->isr_entered = 0; /* an interrupt with no function symbol: the next function
				     * entered is not an interrupt's */
	/* Entered by a call, a jump or an interrupt; not by falling through from the code before
	 * (the start-up code runs into main that way). */
	if (f1 && f1 != f0 && avr->pc == h->funcs[f1 - 1].addr && avr->pc != pc0 + 2u &&
	    avr->pc != pc0 + 4u && !h->funcs[f1 - 1].no_frame && h->nframes < MAX_FRAMES) {
		h->frames[h->nframes++] = (struct frame){(uint16_t)(f1 - 1), sp, h->isr_entered};
		h->isr_entered = 0;
	}
}

/* A run's counts (a tick, or a run of the slow steps) into its part's totals, and into the
 * part's worst if it is the longest. */
static void profile_run_end(struct avrsim *h, enum avrsim_part part, uint64_t len)
{
	int worst = len > h->worst_len[part];

	if (worst)
		h->worst_len[part] = len;
	for (uint32_t i = 0; i < h->nfuncs; i++) {
		struct func *f = &h->funcs[i];

		f->self[part] += f->self_now[part];
		f->incl[part] += f->incl_now[part];
		if (worst) {
			f->self_worst[part] = f->self_now[part];
			f->incl_worst[part] = f->incl_now[part];
		}
		f->self_now[part] = f->incl_now[part] = 0;
	}
}

static void step(struct avrsim *h)
{
	avr_t *avr = h->avr;
	uint64_t c0, d;
	uint32_t pc0;
	uint16_t sp;
	int sleeping, depth0, depth;
	uint8_t pin, portd;

	for (;;) {
		uint64_t c = avr->cycle;

		if (h->nq && h->q[0].cycle <= c) {
			struct event e = ev_pop(h);

			deliver(h, &e);
		} else if (h->phys_next <= c) {
			physics_boundary(h);
		} else if (h->twi_next <= c) {
			twi_bus_event(h);
		} else {
			break;
		}
	}
	arm_wake(h);
	c0 = avr->cycle;
	pc0 = avr->pc;
	sleeping = avr->state == cpu_Sleeping;
	depth0 = avr->interrupts.running_ptr;
	avr_run(avr);
	d = avr->cycle - c0;
	h->st.cycles += d;
	/* Asleep: the whole step if the core was, and all but the instruction's cycle if it
	 * executed SLEEP (simavr sleeps in that same step, often until the interrupt that wakes
	 * it). */
	if (sleeping || (flash_u16(h, pc0) == 0x9588u && d > 1u)) {
		uint64_t idle = sleeping ? d : d - 1u;

		h->st.idle += idle;
		h->period_idle += idle;
		d -= idle; /* what follows counts the cycles awake */
	}
	depth = avr->interrupts.running_ptr;
	/* The instruction ran where depth0 says: in the tick (TICK high, at the depth where it
	 * rose: the main loop with one rate, the timer's interrupt with two), in an interrupt, or
	 * in the main loop (the slow steps while SLOW is high). An interrupt taken after it is
	 * charged its response. */
	if (h->tick_pin && depth0 == h->tick_depth) {
		h->servo_now += d;
		h->period_servo += d;
	} else if (depth0 > 0) {
		uint8_t v = avr->interrupts.running[depth0 - 1]->vector;

		h->st.isr[v].cycles += d;
		h->isr_own[depth0 - 1] += d;
		h->period_isr += d;
	} else if (h->slow_pin) {
		h->slow_now += d;
	}
	if (depth > depth0) { /* an interrupt was taken */
		uint8_t v = avr->interrupts.running[depth - 1]->vector;

		h->isr_own[depth - 1] = ISR_RESPONSE;
		h->st.isr[v].n++;
		h->st.isr[v].cycles += ISR_RESPONSE;
		h->period_isr += ISR_RESPONSE;
		h->period_resp += ISR_RESPONSE;
		if (v == m1284p.vec_twi)
			h->twi_status_in_isr = reg(h, m1284p.twsr) & 0xF8u;
		if (v >= m1284p.vec_pcint[0] && v <= m1284p.vec_pcint[3]) {
			/* PCINT2, 3: the free wheels (encoders 0, 1); PCINT0, 1: the motors */
			uint64_t *at = &h->edge_at[(v - m1284p.vec_pcint[0] + 2) & 3];

			if (*at)
				add_count(&h->st.edge_wait, avr->cycle - *at + ISR_RESPONSE);
			*at = 0;
		}
	} else if (depth < depth0) { /* returned */
		uint8_t v = avr->interrupts.running[depth0 - 1]->vector;
		uint64_t len = h->isr_own[depth0 - 1];

		if (len > h->st.isr[v].max)
			h->st.isr[v].max = len;
		if (v == m1284p.vec_twi)
			add_count(&h->st.twi[h->twi_status_in_isr >> 3], len);
	}
	sp = _avr_sp_get(avr);
	if (sp < h->st.sp_min)
		h->st.sp_min = sp;
	if (h->profiling)
		profile_step(h, pc0, d, depth > depth0, depth < depth0);
	portd = reg(h, m1284p.portd);
	pin = (portd >> PIN_TICK_BIT) & 1u;
	if (pin != h->tick_pin) {
		h->tick_pin = pin;
		if (pin) {
			h->tick_rise = avr->cycle;
			h->tick_depth =
				(uint8_t)depth0; /* where the instruction that raised it ran */
			h->servo_now = 0;
		} else {
			uint64_t len = avr->cycle - h->tick_rise;

			h->ticks++;
			if (h->profiling)
				profile_run_end(h, AVRSIM_PART_TICK, len);
			add_count(&h->st.tick, len);
			add_count(&h->st.servo, h->servo_now);
			on_tick_end(h);
			add_count(slow_tick_ended(h)       ? &h->st.servo_slow
				  : handover_tick_ended(h) ? &h->st.servo_handover
							   : &h->st.servo_other,
				  h->servo_now);
		}
	}
	/* SLOW is PD1 when it is an output (two rates); with one rate PD1 is an input, pulled up */
	pin = (portd & reg(h, m1284p.ddrd)) >> PIN_SLOW_BIT & 1u;
	if (pin != h->slow_pin) {
		h->slow_pin = pin;
		if (pin) {
			h->slow_now = 0;
		} else {
			h->slows++;
			if (h->profiling)
				profile_run_end(h, AVRSIM_PART_SLOW, h->slow_now);
			add_count(&h->st.slow, h->slow_now);
		}
	}
	if (h->freeze_pending) {
		h->freeze_pending = 0;
		timer_stop(h);
	}
	if (avr->state == cpu_Crashed || avr->state == cpu_Done)
		fail(h, "the AVR core stopped (crashed, or sleeping with interrupts off)");
}

/* -1 with the error on stderr if the run failed, else 0. */
static int reported(const struct avrsim *h)
{
	if (!h->error[0])
		return 0;
	fprintf(stderr, "avrsim: %s\n", h->error);
	return -1;
}

int avrsim_run_to_tick_end(struct avrsim *h)
{
	uint64_t n = h->ticks, limit = h->avr->cycle + 100u * AVRSIM_F_CPU / 1000u;

	while (h->ticks == n && !h->error[0]) {
		step(h);
		if (h->avr->cycle > limit)
			fail(h, "no control tick for 100 ms");
	}
	return reported(h);
}

int avrsim_run_to_slow_done(struct avrsim *h)
{
	uint64_t n = h->ticks, limit = h->avr->cycle + 100u * AVRSIM_F_CPU / 1000u;

	while (avrsim_slow_pending(h) && h->ticks == n && !h->error[0]) {
		step(h);
		if (h->avr->cycle > limit)
			fail(h, "the slow steps did not finish in 100 ms");
	}
	return reported(h) ? -1 : h->ticks != n;
}

int avrsim_run_slow_steps(struct avrsim *h)
{
	uint64_t n = h->slows, limit = h->avr->cycle + 100u * AVRSIM_F_CPU / 1000u;

	/* The rates are known from the first tick on. */
	if (!h->tick_hz || !h->slow_shift) {
		if (avrsim_run_to_tick_end(h))
			return -1;
		if (!h->slow_shift)
			return 0;
	}
	while (h->slows == n && !h->error[0]) {
		step(h);
		if (h->avr->cycle > limit)
			fail(h, "no slow steps for 100 ms");
	}
	while (!avrsim_slow_pending(h) && !h->error[0])
		if (avrsim_run_to_tick_end(h))
			return -1;
	return reported(h);
}

int avrsim_run_until_idle(struct avrsim *h)
{
	uint64_t limit = h->avr->cycle + 100u * AVRSIM_F_CPU / 1000u;

	do {
		step(h);
		if (h->avr->cycle > limit)
			fail(h, "the firmware did not sleep for 100 ms");
	} while ((h->avr->state != cpu_Sleeping || h->tick_pin) && !h->error[0]);
	return reported(h);
}

int avrsim_run_cycles(struct avrsim *h, uint64_t n)
{
	uint64_t end = h->avr->cycle + n;

	while (h->avr->cycle < end && !h->error[0])
		step(h);
	return reported(h);
}

static int run_transaction(struct avrsim *h)
{
	uint64_t limit = h->avr->cycle + I2C_TIMEOUT;

	h->opi = 0;
	h->op_begun = 0;
	h->nack = 0;
	/* A new START waits for the bus to be free, and for the firmware to have served the last
	 * STOP (which the TWI holds the next address for). */
	while (!h->held && (h->wait_release || h->avr->cycle < h->bus_free_at) && !h->error[0]) {
		if (h->wait_release && h->avr->cycle >= h->bus_free_at)
			h->st.stop_pending_at_start++;
		while (h->wait_release && !h->error[0])
			step(h);
		while (h->avr->cycle < h->bus_free_at && !h->error[0])
			step(h);
	}
	h->twi_next = h->avr->cycle;
	/* Done when the bus is, and the firmware has finished with its last event (it releases the
	 * bus before it tells the protocol layer). */
	while ((h->opi < h->nops || h->wait_release || h->avr->interrupts.running_ptr ||
		h->twi_vec->pending) &&
	       !h->error[0]) {
		step(h);
		if (h->avr->cycle > limit)
			fail(h, "I2C transaction timed out");
	}
	return reported(h) ? -1 : h->nack ? -1 : 0;
}

int avrsim_i2c_write(struct avrsim *h, const uint8_t *data, uint8_t n, int stop)
{
	uint8_t k = 0;

	if (n > 40)
		return -1;
	h->ops[k++] = (struct op){OP_START, 0};
	h->ops[k++] = (struct op){OP_ADDR, (uint8_t)(h->address << 1)};
	for (uint8_t i = 0; i < n; i++)
		h->ops[k++] = (struct op){OP_TX, data[i]};
	if (stop)
		h->ops[k++] = (struct op){OP_STOP, 0};
	h->nops = k;
	h->rx_out = NULL;
	h->rx_n = 0;
	if (run_transaction(h))
		return -1;
	h->held = !stop;
	return 0;
}

int avrsim_i2c_read(struct avrsim *h, uint8_t *out, uint8_t n)
{
	uint8_t k = 0;

	if (n == 0 || n > 40)
		return -1;
	h->ops[k++] = (struct op){OP_START, 0};
	h->ops[k++] = (struct op){OP_ADDR, (uint8_t)(h->address << 1 | 1)};
	for (uint8_t i = 0; i < n; i++)
		h->ops[k++] = (struct op){OP_RX, (uint8_t)(i + 1 < n)};
	h->ops[k++] = (struct op){OP_STOP, 0};
	h->nops = k;
	h->rx_out = out;
	h->rx_n = n;
	return run_transaction(h);
}

void avrsim_i2c_address(struct avrsim *h, uint8_t address)
{
	h->address = address;
}

void avrsim_tick_enable(struct avrsim *h, int on)
{
	uint8_t *r = &h->avr->data[m1284p.timsk3];

	if (on)
		*r |= (uint8_t)(1u << m1284p.ocie3a);
	else
		*r &= (uint8_t) ~(1u << m1284p.ocie3a);
}

int avrsim_master_hold(struct avrsim *h, int on)
{
	uint8_t *r = &h->avr->data[m1284p.timsk3];
	uint8_t bit = (uint8_t)(1u << m1284p.ocie3a);

	if (h->mode != AVRSIM_EXACT)
		return 0;
	if (on) {
		if (h->hold)
			return 0;
		/* A compare match has come and its tick has not ended: it goes first. */
		if (h->compares != h->ticks)
			return 1;
		h->hold = 1;
		h->hold_ocie = *r & bit;
		*r &= (uint8_t)~bit; /* simavr then only sets the flag (and calls on_compare) */
		return 0;
	}
	if (!h->hold)
		return 0;
	h->hold = 0;
	*r |= h->hold_ocie;
	if (h->compare_held) {
		/* Its interrupt now, as if the compare match came at this cycle; the timer and the
		 * physics have stood still since it came (on_compare). */
		h->compare_held = 0;
		h->releasing = 1;
		avr_raise_interrupt(h->avr, h->t3_vec);
		h->releasing = 0;
	}
	return 0;
}

/* ---------------------------------------------------------------------------------------------
 * Set-up
 */

static void no_sleep(struct avr_t *avr, avr_cycle_count_t howlong)
{
	(void)avr;
	(void)howlong; /* simulated time only: never wait for the wall clock */
}

static int cmp_func(const void *a, const void *b)
{
	const struct func *x = a, *y = b;

	return x->addr < y->addr ? -1 : x->addr > y->addr;
}

/* Symbols and section sizes from the ELF (libelf). */
static int read_elf(struct avrsim *h, const char *path, uint32_t *layout_addr)
{
	int fd = open(path, O_RDONLY);
	Elf *e;
	Elf_Scn *scn = NULL;
	size_t shstrndx;
	int found_board = 0, found_layout = 0;

	if (fd < 0)
		return -1;
	elf_version(EV_CURRENT);
	e = elf_begin(fd, ELF_C_READ, NULL);
	if (!e || elf_getshdrstrndx(e, &shstrndx) != 0) {
		close(fd);
		return -1;
	}
	while ((scn = elf_nextscn(e, scn)) != NULL) {
		GElf_Shdr sh;
		const char *name;

		gelf_getshdr(scn, &sh);
		name = elf_strptr(e, shstrndx, sh.sh_name);
		if (name && !strcmp(name, ".text"))
			h->text_size = (uint32_t)sh.sh_size;
		if (name && !strcmp(name, ".data"))
			h->data_size = (uint32_t)sh.sh_size;
		if (name && (!strcmp(name, ".bss") || !strcmp(name, ".noinit")))
			h->bss_size += (uint32_t)sh.sh_size; /* the board is in .noinit (main.c) */
		if (sh.sh_type != SHT_SYMTAB)
			continue;
		Elf_Data *d = elf_getdata(scn, NULL);
		size_t n = sh.sh_size / sh.sh_entsize;

		h->funcs = calloc(n, sizeof(*h->funcs));
		h->objs = calloc(n, sizeof(*h->objs));
		for (size_t i = 0; i < n; i++) {
			GElf_Sym s;
			const char *sn;

			gelf_getsym(d, (int)i, &s);
			sn = elf_strptr(e, sh.sh_link, s.st_name);
			if (!sn)
				continue;
			/* Functions, and libgcc's assembly routines (no type, but a size). */
			if ((GELF_ST_TYPE(s.st_info) == STT_FUNC ||
			     GELF_ST_TYPE(s.st_info) == STT_NOTYPE) &&
			    s.st_size > 0 && s.st_value < 0x800000u) {
				h->funcs[h->nfuncs].addr = (uint32_t)s.st_value;
				h->funcs[h->nfuncs].size = (uint32_t)s.st_size;
				h->funcs[h->nfuncs].name = strdup(sn);
				h->funcs[h->nfuncs].no_frame = !strncmp(sn, "__tablejump", 11);
				h->nfuncs++;
			}
			if (GELF_ST_TYPE(s.st_info) == STT_OBJECT && s.st_value >= 0x800000u) {
				h->objs[h->nobjs].name = strdup(sn);
				h->objs[h->nobjs].addr = (uint16_t)(s.st_value - 0x800000u);
				h->nobjs++;
			}
			if (!strcmp(sn, "asserv_board")) {
				h->board_addr = (uint16_t)(s.st_value - 0x800000u);
				found_board = 1;
			}
			if (!strcmp(sn, "avr_layout")) {
				*layout_addr = (uint32_t)s.st_value;
				found_layout = 1;
			}
		}
	}
	elf_end(e);
	close(fd);
	if (!found_board || !found_layout) {
		fprintf(stderr, "avrsim: %s has no asserv_board or avr_layout symbol\n", path);
		return -1;
	}
	qsort(h->funcs, h->nfuncs, sizeof(*h->funcs), cmp_func);
	h->func_of_word = calloc(65536u, sizeof(uint16_t));
	for (uint32_t i = 0; i < h->nfuncs; i++)
		for (uint32_t a = h->funcs[i].addr; a < h->funcs[i].addr + h->funcs[i].size; a += 2)
			h->func_of_word[(a >> 1) & 0xFFFFu] = (uint16_t)(i + 1);
	return 0;
}

struct avrsim *avrsim_open(const char *elf_path, uint32_t i2c_hz)
{
	struct avrsim *h = calloc(1, sizeof(*h));
	uint32_t layout_addr = 0;
	uint16_t *lay;
	avr_t *avr;

	if (!h)
		return NULL;
	if (read_elf(h, elf_path, &layout_addr) || elf_read_firmware(elf_path, &h->fw)) {
		fprintf(stderr, "avrsim: cannot read %s\n", elf_path);
		avrsim_close(h);
		return NULL;
	}
	h->elf_path = strdup(elf_path);
	h->i2c_hz = i2c_hz;
	snprintf(h->fw.mmcu, sizeof(h->fw.mmcu), "atmega1284p");
	h->fw.frequency = AVRSIM_F_CPU;
	avr = avr_make_mcu_by_name(h->fw.mmcu);
	if (!avr) {
		avrsim_close(h);
		return NULL;
	}
	h->avr = avr;
	avr_init(avr);
	avr->log = LOG_ERROR; /* not the timer's warnings on PWM mode 10, which it does not model
				 (the harness reads OCR1x itself) */
	avr->sleep = no_sleep;
	avr_load_firmware(avr, &h->fw);
	avr->data[m1284p.mcusr] = (uint8_t)(1u << m1284p.porf); /* a power-on */
	avr->avcc = avr->vcc = avr->aref = AVR_ADC_VREF_MV;

	lay = (uint16_t *)&h->layout;
	for (uint32_t i = 0; i < sizeof(h->layout) / 2u; i++)
		lay[i] = flash_u16(h, layout_addr + 2u * i);
	if (h->layout.magic != AVR_LAYOUT_MAGIC || h->layout.size != sizeof(h->layout)) {
		fprintf(stderr, "avrsim: %s: layout record of another version\n", elf_path);
		avrsim_close(h);
		return NULL;
	}

	for (avr_io_t *io = avr->io_port; io; io = io->next) {
		avr_ioport_t *p = (avr_ioport_t *)io;

		if (!strcmp(io->kind, "port") && p->name >= 'A' && p->name <= 'D')
			h->port[p->name - 'A'] = p;
	}
	for (int p = 0; p < 4; p++) {
		if (!h->port[p]) {
			avrsim_close(h);
			return NULL;
		}
		/* the pins the harness drives: encoders, switches, lines, the bus, the basket */
		h->port[p]->external.pull_mask = (uint8_t[]){0xFC, 0xFF, 0xCF, 0xC4}[p];
	}
	for (int p = 0; p < 4; p++)
		for (int b = 0; b < 8; b++) {
			h->pin[p][b] = avr_io_getirq(avr, AVR_IOCTL_IOPORT_GETIRQ(port_name[p]), b);
			h->pin_level[p][b] = 0xFF; /* unknown: the first set_pin drives it */
		}
	for (int ch = 0; ch < 2; ch++) {
		h->adc[ch] = avr_io_getirq(avr, AVR_IOCTL_ADC_GETIRQ, ADC_IRQ_ADC0 + ch);
		h->adc_mv[ch] = 0xFFFFFFFFu;
	}
	for (int i = 0; i < avr->interrupts.vector_count; i++)
		if (avr->interrupts.vector[i]->vector == m1284p.vec_twi)
			h->twi_vec = avr->interrupts.vector[i];
		else if (avr->interrupts.vector[i]->vector == m1284p.vec_timer3_compa)
			h->t3_vec = avr->interrupts.vector[i];
	/* The TWCR handler is ours (see simavr.md): replace simavr's, which serves the master. */
	avr->io[AVR_DATA_TO_IO(m1284p.twcr)].w.c = twcr_write;
	avr->io[AVR_DATA_TO_IO(m1284p.twcr)].w.param = h;
	avr_irq_register_notify(avr_get_interrupt_irq(avr, m1284p.vec_timer3_compa) +
					AVR_INT_IRQ_PENDING,
				on_compare, h);
	for (int i = 0; i < 3; i++)
		avr_extint_set_strict_lvl_trig(avr, (uint8_t)i, 0);

	/* At rest: encoders at count 0 (A and B low), switches open and no line (high), bus idle,
	 * 0 A. */
	for (int e = 0; e < 4; e++) {
		int port, bit_a;

		enc_pins(e, &port, &bit_a);
		set_pin(h, port, bit_a, 0, 0);
		set_pin(h, port, bit_a + 1, 0, 0);
	}
	{
		struct sim_sensors rest;

		memset(&rest, 0, sizeof(rest));
		schedule_sensors(h, &rest, 0);
	}
	set_bus_pins(h, 1, 1);
	while (h->nq) {
		struct event e = ev_pop(h);

		deliver(h, &e);
	}
	h->bit = AVRSIM_F_CPU / i2c_hz;
	h->address = PROTO_ADDRESS;
	h->twi_next = UINT64_MAX;
	h->phys_next = UINT64_MAX;
	h->st.sp_min = 0xFFFF;
	return h;
}

int avrsim_physics(struct avrsim *h, const struct sim_config *sc, const struct sim_field *f,
		   enum avrsim_lockstep mode)
{
	struct sim_sensors s;

	if (h->ticks || h->sim)
		return -1;
	h->sim = calloc(1, sizeof(*h->sim));
	if (!h->sim || sim_init(h->sim, sc, f))
		return -1;
	h->mode = mode;
	sim_read_sensors(h->sim, &s);
	for (int e = 0; e < 2; e++) {
		h->enc_count[e] = s.enc_total[e];
		h->enc_count[2 + e] = s.motor_total[e];
		if (s.enc_total[e] != 0 || s.motor_total[e] != 0)
			return -1; /* the board starts from count 0 */
	}
	schedule_sensors(h, &s, h->avr->cycle);
	return 0;
}

void avrsim_close(struct avrsim *h)
{
	if (!h)
		return;
	if (h->avr)
		avr_terminate(h->avr);
	for (uint32_t i = 0; i < h->nfuncs; i++)
		free(h->funcs[i].name);
	free(h->funcs);
	for (uint32_t i = 0; i < h->nobjs; i++)
		free(h->objs[i].name);
	free(h->objs);
	free(h->func_of_word);
	free(h->q);
	free(h->sim);
	free(h->elf_path);
	free(h);
}

/* simavr's EEPROM bytes. Its ioctl hands out the array itself when given no buffer (and reports
 * -1 whatever happens: the pointer tells). */
static uint8_t *eeprom_bytes(const struct avrsim *h)
{
	avr_eeprom_desc_t d = {.ee = NULL, .offset = 0, .size = 1};

	avr_ioctl(h->avr, AVR_IOCTL_EEPROM_GET, &d);
	return d.ee;
}

int avrsim_eeprom_read(const struct avrsim *h, uint16_t offset, uint8_t *buf, uint16_t n)
{
	uint8_t *ee = eeprom_bytes(h);

	if (!ee || (uint32_t)offset + n > AVRSIM_EEPROM_SIZE)
		return -1;
	memcpy(buf, ee + offset, n);
	return 0;
}

int avrsim_eeprom_write(struct avrsim *h, uint16_t offset, const uint8_t *buf, uint16_t n)
{
	uint8_t *ee = eeprom_bytes(h);

	if (!ee || (uint32_t)offset + n > AVRSIM_EEPROM_SIZE)
		return -1;
	memcpy(ee + offset, buf, n);
	return 0;
}

/* xorshift32 (Marsaglia 2003): the bytes of a RAM the reset did not keep. */
static uint32_t xorshift32(uint32_t *x)
{
	*x ^= *x << 13;
	*x ^= *x >> 17;
	*x ^= *x << 5;
	return *x;
}

int avrsim_reset(struct avrsim *h, uint8_t mcusr, int keep_ram, uint32_t seed)
{
	avr_t *avr = h->avr;
	uint64_t cycle = avr->cycle;
	uint16_t lo = m1284p.ramstart, n = (uint16_t)(m1284p.ramend + 1u - lo);
	uint8_t *ram = malloc(n);
	uint32_t x = seed | 1u;

	if (!ram || h->opi < h->nops || h->held || h->wait_release) {
		free(ram);
		fprintf(stderr, "avrsim: reset with the bus busy, or out of memory\n");
		return -1;
	}
	memcpy(ram, avr->data + lo, n);
	avr_reset(avr); /* its timers too: the harness's wake-up is armed again below */
	avr->cycle = cycle;
	if (!keep_ram)
		for (uint16_t i = 0; i < n; i++)
			ram[i] = (uint8_t)xorshift32(&x);
	memcpy(avr->data + lo, ram, n);
	free(ram);
	avr->data[m1284p.mcusr] = mcusr;
	h->wake_armed = 0;
	/* The reset cleared the PINx registers: the wires' levels again, and the analog inputs. */
	for (int p = 0; p < 4; p++)
		for (int b = 0; b < 8; b++)
			if (h->port[p]->external.pull_mask >> b & 1u)
				avr_raise_irq(h->pin[p][b],
					      h->port[p]->external.pull_value >> b & 1u);
	for (int ch = 0; ch < 2; ch++)
		if (h->adc_mv[ch] != 0xFFFFFFFFu)
			avr_raise_irq(h->adc[ch], h->adc_mv[ch]);
	return reported(h);
}

struct avrsim *avrsim_power_cycle(struct avrsim *h)
{
	static uint8_t kept[AVRSIM_EEPROM_SIZE];
	char *path = strdup(h->elf_path);
	uint32_t i2c_hz = h->i2c_hz;
	struct avrsim *n = NULL;

	if (path && avrsim_eeprom_read(h, 0, kept, sizeof(kept)) == 0) {
		avrsim_close(h);
		h = NULL;
		n = avrsim_open(path, i2c_hz);
		if (n && avrsim_eeprom_write(n, 0, kept, sizeof(kept)) != 0) {
			avrsim_close(n);
			n = NULL;
		}
	}
	if (!n)
		fprintf(stderr, "avrsim: the power cycle failed\n");
	avrsim_close(h);
	free(path);
	return n;
}

/* ---------------------------------------------------------------------------------------------
 * Accessors, statistics, profile
 */

int avrsim_encoders_turn(struct avrsim *h, const double counts_per_s[4])
{
	if (h->sim)
		return -1;
	for (int e = 0; e < 4; e++)
		h->synth_rate[e] = counts_per_s[e];
	if (h->phys_next == UINT64_MAX)
		h->phys_next = h->avr->cycle;
	return 0;
}

int avrsim_sensors_set(struct avrsim *h, const struct sim_sensors *s)
{
	if (h->sim)
		return -1;
	schedule_sensors(h, s, h->avr->cycle);
	return 0;
}

int64_t avrsim_encoder_edges(const struct avrsim *h, int e)
{
	return h->enc_delivered[e];
}

int avrsim_symbol(const struct avrsim *h, const char *name, uint16_t *addr)
{
	for (uint32_t i = 0; i < h->nobjs; i++)
		if (!strcmp(h->objs[i].name, name)) {
			*addr = h->objs[i].addr;
			return 0;
		}
	return -1;
}

int avrsim_interrupts_idle(const struct avrsim *h)
{
	return h->avr->interrupts.running_ptr == 0 && !avr_has_pending_interrupts(h->avr);
}

uint16_t avrsim_board(const struct avrsim *h)
{
	return h->board_addr;
}

const struct avr_layout *avrsim_layout(const struct avrsim *h)
{
	return &h->layout;
}

const struct sim *avrsim_sim(const struct avrsim *h)
{
	return h->sim;
}

uint64_t avrsim_cycle(const struct avrsim *h)
{
	return h->avr->cycle;
}

uint64_t avrsim_next_compare(const struct avrsim *h)
{
	uint64_t p = h->period_cycles ? h->period_cycles : AVRSIM_F_CPU / 1000u;

	return h->mode == AVRSIM_EXACT ? h->next_compare : h->last_compare + p;
}

uint64_t avrsim_ticks(const struct avrsim *h)
{
	return h->ticks;
}

uint8_t avrsim_slow_shift(const struct avrsim *h)
{
	return h->slow_shift;
}

int avrsim_slow_pending(const struct avrsim *h)
{
	return h->slow_shift &&
	       (h->slow_pin || reg(h, (uint16_t)(h->board_addr + h->layout.slow_due)) != 0);
}

const struct avrsim_stats *avrsim_stats(const struct avrsim *h)
{
	return &h->st;
}

void avrsim_stats_reset(struct avrsim *h)
{
	memset(&h->st, 0, sizeof(h->st));
	h->st.sp_min = 0xFFFF;
}

void avrsim_profile(struct avrsim *h, int on, int tick_only)
{
	for (uint32_t i = 0; i < h->nfuncs; i++)
		for (int p = 0; p < 2; p++)
			h->funcs[i].self[p] = h->funcs[i].incl[p] = h->funcs[i].self_now[p] =
				h->funcs[i].incl_now[p] = 0;
	h->worst_len[0] = h->worst_len[1] = 0;
	h->profiling = on;
	h->profile_tick_only = tick_only;
	h->nframes = 0;
}

struct ranked {
	const struct func *f;
	uint64_t incl, self;
};

static int cmp_ranked(const void *a, const void *b)
{
	const struct ranked *x = a, *y = b;

	return x->incl < y->incl ? 1 : x->incl > y->incl ? -1 : 0;
}

void avrsim_profile_report(const struct avrsim *h, FILE *out, enum avrsim_part part, int top,
			   uint64_t per, int worst)
{
	struct ranked *v = malloc(h->nfuncs * sizeof(*v));
	int n = 0;

	if (!v || per == 0) {
		free(v);
		return;
	}
	for (uint32_t i = 0; i < h->nfuncs; i++) {
		const struct func *f = &h->funcs[i];
		uint64_t incl = worst ? f->incl_worst[part] : f->incl[part];

		if (incl)
			v[n++] = (struct ranked){f, incl,
						 worst ? f->self_worst[part] : f->self[part]};
	}
	qsort(v, (size_t)n, sizeof(*v), cmp_ranked);
	fprintf(out, "  %-28s %12s %12s\n", "function", "inclusive", "self");
	for (int i = 0; i < n && i < top; i++)
		fprintf(out, "  %-28s %12.0f %12.0f\n", v[i].f->name,
			(double)v[i].incl / (double)per, (double)v[i].self / (double)per);
	free(v);
}

void avrsim_sizes(const struct avrsim *h, uint32_t *flash, uint32_t *ram)
{
	*flash = h->text_size + h->data_size;
	*ram = h->data_size + h->bss_size;
}
