/* Polar control (see control.h). */
#include "control.h"

#include <stddef.h>

#include "fixmath.h"
#include "protocol_defs.h"

/* Coefficient per m/s [duty_q15] -> per um/s [duty_q15 * 2^20]. */
static int32_t per_um_q20(int32_t per_m)
{
	return (int32_t)fx_div_round64((int64_t)per_m << 20, 1000000);
}

/* v clipped to +-lim, for a lim in 0..32767. */
static inline int16_t clip16(int32_t v, int16_t lim)
{
	if (v > lim)
		return lim;
	if (v < -lim)
		return (int16_t)-lim;
	return (int16_t)v;
}

#if CONFIG_QUIET_SERVO
/* The derivative's low-pass of d_filter_ms [ms] at tick_hz: 2^k ticks, the nearest power of
 * two (within a factor sqrt 2), 0..PID_D_SHIFT_MAX; 0 ms (or under 1.5 ticks) gives 0, the raw
 * difference. */
static uint8_t d_shift_of(uint8_t ms, uint16_t tick_hz)
{
	uint32_t ticks_x2 = ((uint32_t)ms * tick_hz * 2 + 500) / 1000; /* 2 ticks, rounded */
	uint8_t k = 0;

	/* the largest k with 2^k <= ticks sqrt 2: 2^(2k) <= (2 ticks)^2 / 2 */
	while (k < PID_D_SHIFT_MAX && ((uint32_t)1 << (2 * k + 2)) <= ticks_x2 * ticks_x2 / 2)
		k++;
	return k;
}
#endif

static struct pid_config pid_config_of(const struct control_config *cfg, uint16_t tick_hz,
				       const struct control_gains *g)
{
	struct pid_config pc;

	pc.p = g->p;
	pc.i = g->i;
	pc.d = g->d;
	pc.out_limit_q15 = cfg->duty_max_q15;
	pc.tick_hz = tick_hz;
#if CONFIG_QUIET_SERVO
	pc.d_shift = d_shift_of(cfg->d_filter_ms, tick_hz);
	pc.d_lag_max_um = cfg->d_lag_max_um;
#endif
	return pc;
}

int control_init(struct control *c, const struct control_config *cfg, uint16_t tick_hz)
{
	struct pid_config pc;

	if (cfg->duty_max_q15 <= 0 || cfg->ff_speed_q15_per_m_s < 0 ||
	    cfg->ff_speed_q15_per_m_s > 1000000 || cfg->ff_accel_q15_per_m_s2 < 0 ||
	    cfg->ff_accel_q15_per_m_s2 > 1000000 || cfg->ff_angle_accel_q15_per_m_s2 < 0 ||
	    cfg->ff_angle_accel_q15_per_m_s2 > 1000000 || tick_hz == 0)
		return -1;
	for (int i = 0; i < 2; i++)
		if (cfg->gain_slew_q15_per_s[i] < 1 ||
		    cfg->gain_slew_q15_per_s[i] > ((int32_t)1 << 24))
			return -1;
	c->cfg = *cfg;
	c->tick_hz = tick_hz;
	c->k_speed_q20 = per_um_q20(cfg->ff_speed_q15_per_m_s);
	c->k_accel_q20 = per_um_q20(cfg->ff_accel_q15_per_m_s2);
	c->k_angle_accel_q20 = per_um_q20(cfg->ff_angle_accel_q15_per_m_s2);
	c->ff_narrow = c->k_speed_q20 <= 0xffff && c->k_accel_q20 <= 0xffff &&
		       c->k_angle_accel_q20 <= 0xffff;
	for (int i = 0; i < 2; i++) { /* the term of no acceleration, for any coefficient */
		c->ff_acc[i].acc_um_s2 = 0;
		c->ff_acc[i].term_q15 = 0;
	}
	c->gains = cfg->presets[FILTRE_STD];
	pc = pid_config_of(cfg, tick_hz, &c->gains);
	if (pid_init(&c->dist, &pc) || pid_init(&c->angle, &pc))
		return -1;
	for (int i = 0; i < 2; i++) { /* at least 1 a tick, so that a step always ends */
		c->slew_q15[i] = (int32_t)fx_div_round64(cfg->gain_slew_q15_per_s[i], tick_hz);
		if (c->slew_q15[i] < 1)
			c->slew_q15[i] = 1;
	}
	c->bump_pending = 0;
	c->bumping = 0;
	c->bump_q15[0] = 0;
	c->bump_q15[1] = 0;
	c->dist_err_um = 0;
	c->angle_err_um = 0;
	c->duty_q15[0] = 0;
	c->duty_q15[1] = 0;
	return 0;
}

void control_set_gains(struct control *c, const struct control_gains *g)
{
	struct pid_config pc = pid_config_of(&c->cfg, c->tick_hz, g);

	c->gains = *g;
	/* The output as the old gains left it, step included: the next tick measures the new
	 * gains' step from it (issue 31: the stiffer P's correction of a following error that
	 * softer gains had let grow, applied at once, asked a wheel for more than its grip). */
	c->bump_from_q15[0] = clip16(c->dist.out_q15 + c->bump_q15[0], c->cfg.duty_max_q15);
	c->bump_from_q15[1] = clip16(c->angle.out_q15 + c->bump_q15[1], c->cfg.duty_max_q15);
	c->bump_pending = 3;
	c->bumping = 1;
	pid_set_config(&c->dist, &pc);
	pid_set_config(&c->angle, &pc);
}

void control_reset(struct control *c)
{
	pid_reset(&c->dist);
	pid_reset(&c->angle);
	c->bump_pending = 0;
	c->bumping = 0;
	c->bump_q15[0] = 0;
	c->bump_q15[1] = 0;
}

/* The PID output u of axis i (0 distance, 1 angle) with what is left of a change of gains'
 * step: the first tick after the change gives the old output, and the step then goes by
 * slew_q15[i] a tick. Called only while bumping. */
static int32_t bumpless(struct control *c, uint8_t i, int16_t u)
{
	int32_t b;

	if (c->bump_pending & (1u << i)) {
		c->bump_pending &= (uint8_t) ~(1u << i);
		c->bump_q15[i] = (int32_t)c->bump_from_q15[i] - u;
	}
	b = c->bump_q15[i];
	if (b > c->slew_q15[i])
		c->bump_q15[i] = b - c->slew_q15[i];
	else if (b < -c->slew_q15[i])
		c->bump_q15[i] = b + c->slew_q15[i];
	else
		c->bump_q15[i] = 0;
	if (!c->bump_pending && c->bump_q15[0] == 0 && c->bump_q15[1] == 0)
		c->bumping = 0;
	return u + b;
}

/* round(v k / 2^20) for a coefficient k <= 2^20 (1 full duty per m/s): two 16 x 16 products for
 * the usual coefficients below 2^16, and two more above (rounded twice: within one unit). The
 * velocity and acceleration stay below 2^24 (the profiles' limits). */
static int32_t ff_term_c(int32_t v, int32_t k)
{
	int32_t r = fx_mul_q(v, (int32_t)fx_lo16((uint32_t)k), 20);

	if (k > 0xffff)
		r += fx_mul_q(v, (int32_t)fx_hi16((uint32_t)k), 4);
	return r;
}

/* round(v k / 2^20): by the architecture's kernel for the coefficients below 2^16, which the
 * reference robot's are (ff_narrow, control_init). */
static inline int32_t ff_term(const struct control *c, int32_t v, int32_t k)
{
	if (c->ff_narrow)
		return fx_mul_q20_u16(v, fx_lo16((uint32_t)k));
	return ff_term_c(v, k);
}

/* Feed-forward of one axis [duty_q15]: the velocity's term, and the acceleration's (k_accel,
 * that axis's coefficient) from m. The set points' acceleration holds over a slow period (the
 * servo steps their position and velocity towards the slow steps' next ones, not their
 * acceleration), so its term is computed once a period, when the acceleration changes: one
 * product a tick where it took two, accelerating. */
static inline int32_t feed_forward(const struct control *c, struct control_ff_memo *m,
				   int32_t k_accel, const struct orders_axis *sp)
{
	if (sp->acc_um_s2 != m->acc_um_s2) {
		m->acc_um_s2 = sp->acc_um_s2;
		m->term_q15 = ff_term(c, sp->acc_um_s2, k_accel);
	}
	return ff_term(c, sp->vel_um_s, c->k_speed_q20) + m->term_q15;
}

void control_update(struct control *c, const struct orders_axis *sp_dist,
		    const struct orders_axis *sp_angle, int32_t dist_um, int32_t angle_um)
{
	int32_t u;
	int16_t lim, a, head, d;

	c->dist_err_um = sp_dist->pos_um - dist_um;
	c->angle_err_um = sp_angle->pos_um - angle_um;
	/* Steering first: when the sum would saturate a motor, the distance command gives way,
	 * so the robot keeps its heading (a saturated turn would otherwise curve the path). */
	u = pid_update(&c->angle, c->angle_err_um);
	if (c->bumping)
		u = bumpless(c, 1, (int16_t)u);
	u += feed_forward(c, &c->ff_acc[1], c->k_angle_accel_q20, sp_angle);
	lim = c->cfg.duty_max_q15;
	a = clip16(u, lim);
	head = (int16_t)(lim - (a < 0 ? -a : a));
	u = pid_update(&c->dist, c->dist_err_um);
	if (c->bumping)
		u = bumpless(c, 0, (int16_t)u);
	u += feed_forward(c, &c->ff_acc[0], c->k_accel_q20, sp_dist);
	d = clip16(u, head);
	c->duty_q15[0] = (int16_t)(d - a); /* left */
	c->duty_q15[1] = (int16_t)(d + a);
}

void control_off(struct control *c)
{
	control_reset(c);
#if CONFIG_QUIET_SERVO
	/* The PIDs do not run while the motors are off: the speed they read goes stale. */
	pid_forget(&c->dist);
	pid_forget(&c->angle);
#endif
	c->duty_q15[0] = 0;
	c->duty_q15[1] = 0;
}
