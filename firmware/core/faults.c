/* Stop conditions other than arrival (see faults.h). */
#include "faults.h"

#include "fixmath.h"

#define N_FAULT_TIMES 8u

static int32_t abs32(int32_t v)
{
	return v < 0 ? -v : v;
}

int faults_init(struct faults *f, const struct faults_config *cfg, const uint16_t motor_count[2])
{
	if (cfg->repeat_max == 0 || cfg->repeat_max > N_FAULT_TIMES || cfg->slip_shift > 12 ||
	    cfg->following_ticks == 0 || cfg->current_ticks == 0 || cfg->slip_max_um > 30000)
		return -1;
	f->cfg = *cfg;
	f->last_motor[0] = motor_count[0];
	f->last_motor[1] = motor_count[1];
	f->following_count = 0;
	f->current_count = 0;
	f->slip_dist_q16 = 0;
	f->slip_angle_q16 = 0;
	f->lost_um[0] = 0;
	f->lost_um[1] = 0;
	f->now = 0;
	for (uint8_t i = 0; i < N_FAULT_TIMES; i++)
		f->motor_fault_at[i] = 0;
	f->n_motor_faults = 0;
	f->shock_ignored = 0;
	f->grave = 0;
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

/* v / 2^n rounded (ties away from zero), n = slip_shift (0..12): a shift of the magnitude. */
static int32_t shr_round(int32_t v, uint8_t n)
{
	return fx_shr_round(v, n);
}

static uint8_t slip_and_lost(struct faults *f, const struct faults_inputs *in)
{
	int32_t m[2], diff_d, diff_a, free_a;

	m[0] = motor_step_q16(f, 0, in->motor_count[0]);
	m[1] = motor_step_q16(f, 1, in->motor_count[1]);
	if (!f->cfg.motor_encoders)
		return FAULTS_NONE;

	/* Slip: the drive wheels' travel against the free wheels', on both polar axes (the
	 * angle axis scaled from the encoder track to the drive track), summed with a leak so
	 * that a short disagreement (a seam, backlash) is forgotten. Halves are taken after the
	 * sum to keep the rounding out of the comparison. */
	free_a = in->free_ratio_q16 <= 0xffff
			 ? fx_mul_q(in->free_step_q16[1] - in->free_step_q16[0], in->free_ratio_q16,
				    16)
			 : fx_mul_shr(in->free_step_q16[1] - in->free_step_q16[0],
				      in->free_ratio_q16, 16);
	diff_d = (m[0] + m[1]) - (in->free_step_q16[0] + in->free_step_q16[1]);
	diff_a = (m[1] - m[0]) - free_a;
	f->slip_dist_q16 +=
		fx_shr_round(diff_d, 1) - shr_round(f->slip_dist_q16, f->cfg.slip_shift);
	f->slip_angle_q16 +=
		fx_shr_round(diff_a, 1) - shr_round(f->slip_angle_q16, f->cfg.slip_shift);

	/* Encoder signal lost: one free wheel stands still while its motor turns and the other
	 * free wheel counts. Both standing still is a slip (the robot is stuck), not a wire. */
	for (uint8_t s = 0; s < 2; s++) {
		if (in->free_step_q16[s] != 0)
			f->lost_um[s] = 0;
		else if (f->lost_um[s] < INT32_MAX / 2)
			f->lost_um[s] += (int32_t)fx_hi16((uint32_t)abs32(m[s]) + 0x8000u);
	}
	for (uint8_t s = 0; s < 2; s++) {
		if (f->lost_um[s] > f->cfg.lost_min_um && f->lost_um[1 - s] == 0) {
			f->cause = FAULTS_CAUSE_ENCODER_LOST;
			return FAULTS_GRAVE;
		}
	}
	if (abs32(f->slip_dist_q16) > (f->cfg.slip_max_um << 16) ||
	    abs32(f->slip_angle_q16) > (f->cfg.slip_max_um << 16)) {
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
		if (f->now - oldest <= f->cfg.repeat_window_ticks) {
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
	over = abs32(in->current_ma[0]) > f->cfg.current_max_ma ||
	       abs32(in->current_ma[1]) > f->cfg.current_max_ma;
	if (counted(&f->current_count, over, f->cfg.current_ticks) && ev == FAULTS_NONE) {
		ev = FAULTS_MOTOR;
		f->cause = FAULTS_CAUSE_OVERCURRENT;
	}
	blocked = in->moving && !in->pushing &&
		  (abs32(in->dist_err_um) > f->cfg.following_max_um ||
		   abs32(in->angle_err_um) > f->cfg.following_max_um);
	if (counted(&f->following_count, blocked, f->cfg.following_ticks) && ev == FAULTS_NONE) {
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
