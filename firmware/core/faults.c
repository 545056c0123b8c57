/* Stop conditions other than arrival (see faults.h). */
#include "faults.h"

#include "fixmath.h"

#define N_FAULT_TIMES 8u

/* A wheel travel above 4 mm in one tick (4 m/s) is a glitch: clamped there, the sums of four
 * travels below fit in 32 bits [um * 2^16]. */
#define STEP_MAX_Q16 ((int32_t)1 << 28)

static int32_t clamp_step(int32_t v)
{
	return v > STEP_MAX_Q16 ? STEP_MAX_Q16 : v < -STEP_MAX_Q16 ? -STEP_MAX_Q16 : v;
}

/* The lost check's sums stop growing here, so that three times one of them fits. */
#define LOST_SUM_MAX (INT32_MAX / 4)

int faults_init(struct faults *f, const struct faults_config *cfg, uint16_t rate_hz,
		const uint16_t motor_count[2])
{
	uint16_t slip_ticks;

	if (cfg->repeat_max == 0 || cfg->repeat_max > N_FAULT_TIMES || rate_hz == 0 ||
	    cfg->following_ms == 0 || cfg->current_ms == 0 || cfg->slip_window_ms == 0 ||
	    cfg->slip_max_um > 30000)
		return -1;
	slip_ticks = fx_ticks_of_ms(cfg->slip_window_ms, rate_hz);
	if (slip_ticks > 4096)
		return -1;
	f->cfg = *cfg;
	f->following_ticks = fx_ticks_of_ms(cfg->following_ms, rate_hz);
	f->current_ticks = fx_ticks_of_ms(cfg->current_ms, rate_hz);
	f->repeat_window_ticks = fx_ticks_of_ms(cfg->repeat_window_ms, rate_hz);
	f->slip_shift = (uint8_t)(fx_bit_length32(slip_ticks) - 1u);
	f->last_motor[0] = motor_count[0];
	f->last_motor[1] = motor_count[1];
	f->following_count = 0;
	f->current_count = 0;
	f->slip_dist_q16 = 0;
	f->slip_angle_q16 = 0;
	for (uint8_t s = 0; s < 2; s++) {
		f->lost_motor_um[s] = 0;
		f->lost_other_um[s] = 0;
	}
	f->now = 0;
	for (uint8_t i = 0; i < N_FAULT_TIMES; i++)
		f->motor_fault_at[i] = 0;
	f->n_motor_faults = 0;
	f->shock_ignored = 0;
	f->grave = 0;
	f->lost_suspect = 0;
	f->cause = FAULTS_CAUSE_NONE;
	return 0;
}

void faults_order_started(struct faults *f, uint8_t shocks_now)
{
	f->shock_ignored = shocks_now;
}

/* Drive wheel travel this tick from a wrapping motor counter [um * 2^16], saturated: counts
 * times the factor from two 16 x 16 products. */
static int32_t motor_step_q16(struct faults *f, uint8_t side, uint16_t count)
{
	uint16_t d = (uint16_t)(count - f->last_motor[side]);
	uint8_t neg = d >= 0x8000u;
	uint16_t m = neg ? (uint16_t)(0u - d) : d;
	uint32_t k = f->cfg.motor_um_per_count_q16;
	uint32_t lo = fx_mul_u16(m, fx_lo16(k));
	uint32_t hi = fx_mul_u16(m, fx_hi16(k)) + fx_hi16(lo);
	int32_t t = hi >= 0x8000u ? INT32_MAX : (int32_t)((hi << 16) | fx_lo16(lo));

	f->last_motor[side] = count;
	return neg ? -t : t;
}

/* Encoder signal lost: while an order drives the motors, a free wheel gives not a single
 * count while its motor turns lost_min_um and the other free wheel rolls at least a
 * third as far (summed with its sign, so that the twitches of a blocked robot cancel
 * out). A robot blocked on one side, pivoting on the contact with that side's drive wheel
 * spinning, can look the same for a while, so the first time is a suspicion: the order is
 * abandoned (PB_MOTEUR, which that collision deserves anyway). The wheel's next count
 * clears it; a cut wire never counts again, and the next order that turns the motor as
 * far, whatever the other wheel does, is PB_GRAVE. A dead wheel makes the robot steer
 * and slip at once, so while one is on its way to a verdict (at most lost_min_um of
 * motor travel) the slip check waits. */
static uint8_t lost_wheels(struct faults *f, const struct faults_inputs *in, const int32_t m[2],
			   const int32_t fr[2], uint8_t *lost_pending)
{
	for (uint8_t s = 0; s < 2; s++) {
		uint8_t o = (uint8_t)(1u - s);
		uint8_t bit = (uint8_t)(1u << s);

		if (in->free_step_q16[s] != 0)
			f->lost_suspect &= (uint8_t)~bit;
		if (in->free_step_q16[s] != 0 || !in->moving) {
			f->lost_motor_um[s] = 0;
			f->lost_other_um[s] = 0;
			continue;
		}
		if (f->lost_motor_um[s] < LOST_SUM_MAX &&
		    fx_abs32(f->lost_other_um[s]) < LOST_SUM_MAX) {
			f->lost_motor_um[s] += (int32_t)fx_hi16((uint32_t)fx_abs32(m[s]) + 0x8000u);
			f->lost_other_um[s] += fx_shr_round(fr[o], 16);
		}
		if (!(f->lost_suspect & bit) &&
		    fx_abs32(f->lost_other_um[s]) * 3 < f->lost_motor_um[s])
			continue;
		if (f->lost_motor_um[s] > f->cfg.lost_min_um) {
			f->cause = FAULTS_CAUSE_ENCODER_LOST;
			f->lost_motor_um[s] = 0;
			f->lost_other_um[s] = 0;
			if (f->lost_suspect & bit)
				return FAULTS_GRAVE;
			f->lost_suspect |= bit;
			return FAULTS_MOTOR;
		}
		if (f->lost_motor_um[s] > 0)
			*lost_pending = 1;
	}
	return FAULTS_NONE;
}

static uint8_t slip_and_lost(struct faults *f, const struct faults_inputs *in)
{
	int32_t m[2], fr[2], diff_d, diff_a, free_a, neg_a;
	uint8_t lost_pending = 0, ev;

	m[0] = clamp_step(motor_step_q16(f, 0, in->motor_count[0]));
	m[1] = clamp_step(motor_step_q16(f, 1, in->motor_count[1]));
	if (!f->cfg.motor_encoders)
		return FAULTS_NONE;
	fr[0] = clamp_step(in->free_step_q16[0]);
	fr[1] = clamp_step(in->free_step_q16[1]);

	/* Slip: the drive wheels' travel against the free wheels', on both polar axes (the
	 * angle axis scaled from the encoder track to the drive track), summed with a leak so
	 * that a short disagreement (a seam, backlash) is forgotten. Halves are taken after the
	 * sum to keep the rounding out of the comparison. */
	/* Clamped like the steps: a large ratio (SET_ODOMETRIE's shortest encoder track against a
	 * long drive track) would saturate the product to INT32_MIN, and the difference below
	 * overflow (found by fuzz/fuzz_board). */
	free_a = clamp_step(in->free_ratio_q16 <= 0xffff
				    ? fx_mul_q(fr[1] - fr[0], in->free_ratio_q16, 16)
				    : fx_mul_shr(fr[1] - fr[0], in->free_ratio_q16, 16));
	diff_d = (m[0] + m[1]) - (fr[0] + fr[1]);
	diff_a = (m[1] - m[0]) - free_a;
	f->slip_dist_q16 =
		fx_add_sat32(f->slip_dist_q16 - fx_shr_round(f->slip_dist_q16, f->slip_shift),
			     fx_shr_round(diff_d, 1));
	f->slip_angle_q16 =
		fx_add_sat32(f->slip_angle_q16 - fx_shr_round(f->slip_angle_q16, f->slip_shift),
			     fx_shr_round(diff_a, 1));
	if (!in->moving) {
		/* No order to abandon: a robot pushed while it holds its position, or rocking
		 * after an order was abandoned, is not a motor problem. */
		f->slip_dist_q16 = 0;
		f->slip_angle_q16 = 0;
	}

	ev = lost_wheels(f, in, m, fr, &lost_pending);
	if (ev != FAULTS_NONE)
		return ev;
	/* Each drive wheel's own slip, the half-sums added (left d - a, right d + a): one wheel
	 * spinning on a slippery patch shows its whole slip there, where each polar axis shows
	 * half of it (issue 18: 105 ms to detect at 5 % of the grip, now docs/failure-model.md). */
	neg_a = f->slip_angle_q16 == INT32_MIN ? INT32_MAX : -f->slip_angle_q16;
	if (!lost_pending &&
	    (fx_abs32(fx_add_sat32(f->slip_dist_q16, f->slip_angle_q16)) >
		     (f->cfg.slip_max_um << 16) ||
	     fx_abs32(fx_add_sat32(f->slip_dist_q16, neg_a)) > (f->cfg.slip_max_um << 16))) {
		f->cause = FAULTS_CAUSE_SLIP;
		f->slip_dist_q16 = 0;
		f->slip_angle_q16 = 0;
		return FAULTS_MOTOR;
	}
	return FAULTS_NONE;
}

static uint8_t counted(uint16_t *count, int cond, uint16_t limit)
{
	if (!cond) {
		*count = 0;
		return 0;
	}
	if (*count < 0xFFFFu)
		(*count)++;
	return *count >= limit;
}

/* A PB_MOTEUR: the last repeat_max of them within the window make a PB_GRAVE. */
static uint8_t motor_fault(struct faults *f, uint8_t cause)
{
	uint8_t n = f->cfg.repeat_max;
	uint32_t oldest;

	f->cause = cause;
	f->motor_fault_at[f->n_motor_faults % N_FAULT_TIMES] = f->now;
	if (f->n_motor_faults < 255u)
		f->n_motor_faults++;
	if (f->n_motor_faults >= n) {
		oldest = f->motor_fault_at[(uint8_t)(f->n_motor_faults - n) % N_FAULT_TIMES];
		if (f->now - oldest <= f->repeat_window_ticks) {
			f->cause = FAULTS_CAUSE_REPEATED;
			return FAULTS_GRAVE;
		}
	}
	return FAULTS_MOTOR;
}

uint8_t faults_check(struct faults *f, const struct faults_inputs *in)
{
	uint8_t ev;
	uint8_t shocks;
	int over, blocked;

	f->now++;
	f->shock_ignored &= in->shocks;
	shocks = in->shocks & (uint8_t)~f->shock_ignored;
	if (f->grave) {
		slip_and_lost(f, in); /* keep the motor counters current */
		return FAULTS_GRAVE;
	}
	ev = slip_and_lost(f, in);
	over = fx_abs32(in->current_ma[0]) > f->cfg.current_max_ma ||
	       fx_abs32(in->current_ma[1]) > f->cfg.current_max_ma;
	if (counted(&f->current_count, over, f->current_ticks) && ev == FAULTS_NONE) {
		f->current_count = 0;
		if (!in->moving)
			return FAULTS_YIELD; /* holding against a push: let go, no order to stop */
		ev = FAULTS_MOTOR;
		f->cause = FAULTS_CAUSE_OVERCURRENT;
	}
	blocked = in->moving && !in->pushing &&
		  (fx_abs32(in->dist_err_um) > f->cfg.following_max_um ||
		   fx_abs32(in->angle_err_um) > f->cfg.following_max_um);
	if (counted(&f->following_count, blocked, f->following_ticks) && ev == FAULTS_NONE) {
		ev = FAULTS_MOTOR;
		f->cause = FAULTS_CAUSE_FOLLOWING;
	}
	if (ev == FAULTS_MOTOR) {
		/* An abandoned order stops the robot: the checks start again from zero. */
		f->following_count = 0;
		f->current_count = 0;
		ev = motor_fault(f, f->cause);
	}
	if (ev == FAULTS_GRAVE) {
		f->grave = 1;
		return ev;
	}
	if (ev != FAULTS_NONE || !in->moving)
		return ev;
	if (in->pushing)
		shocks &= (uint8_t)~f->cfg.shock_basket_mask; /* the expected contact */
	if (shocks & (uint8_t)~f->cfg.shock_basket_mask)
		return FAULTS_SHOCK_BORD;
	if (shocks)
		return FAULTS_SHOCK_PANIER;
	return FAULTS_NONE;
}
