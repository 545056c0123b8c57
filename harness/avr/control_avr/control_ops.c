/* The operations of control_avr.h on one pid and one control, the same source on the AVR and on
 * the host (see control_avr.h). */
#include <string.h>

#include "control_avr.h"

/* The pid's settings as converted and its state: res[0..15]. */
static void pid_dump(const struct pid *c, int32_t *res)
{
	res[0] = c->kp_q12;
	res[1] = c->kd_q12;
	res[2] = (int32_t)c->ki_q24;
	res[3] = c->p_err_max_um;
	res[4] = c->d_err_max_um;
	res[5] = c->fast.p_err_um;
	res[6] = c->fast.d_err_um;
	res[7] = c->i_max_q8;
	res[8] = c->i_acc_q24.hi;
	res[9] = c->i_acc_q24.lo;
	res[10] = c->prev_err_um;
	res[11] = c->has_prev;
	res[12] = c->out_q15;
#if CONFIG_QUIET_SERVO
	res[13] = c->d_lp;
	res[14] = c->d_last_um;
	res[15] = c->raw_d;
#endif
}

/* The state a pid keeps across ticks: res[0..4], and its derivative's low-pass: low[0..1]. */
static void pid_state(const struct pid *c, int32_t *res, int32_t *low)
{
	res[0] = c->i_acc_q24.hi;
	res[1] = c->i_acc_q24.lo;
	res[2] = c->prev_err_um;
	res[3] = c->has_prev;
	res[4] = c->out_q15;
#if CONFIG_QUIET_SERVO
	low[0] = c->d_lp;
	low[1] = c->d_last_um;
#else
	(void)low;
#endif
}

static void pid_config_of(const int32_t *arg, struct pid_config *pc)
{
	pc->p = (uint16_t)arg[0];
	pc->i = (uint16_t)arg[1];
	pc->d = (uint16_t)arg[2];
	pc->out_limit_q15 = (int16_t)arg[3];
	pc->tick_hz = (uint16_t)arg[4];
#if CONFIG_QUIET_SERVO
	pc->d_shift = (uint8_t)arg[5];
	pc->d_lag_max_um = arg[6];
#endif
}

static void axis_of(const int32_t *arg, struct orders_axis *sp)
{
	sp->pos_um = arg[0];
	sp->vel_um_s = arg[1];
	sp->acc_um_s2 = arg[2];
}

void cta_run(struct cta_state *s, uint8_t op, const int32_t *arg, int32_t *res)
{
	struct pid_config pc;
	struct control_config cc;
	struct control_gains g;
	struct orders_axis sd, sa;
	struct control *c = &s->ctl;
	int32_t ret = 0;

	switch (op) {
	case CTA_PID_INIT:
		pid_config_of(arg, &pc);
		ret = pid_init(&s->pid, &pc);
		break;
	case CTA_PID_SET:
		pid_config_of(arg, &pc);
		ret = pid_set_config(&s->pid, &pc);
		break;
	case CTA_PID_RESET:
		pid_reset(&s->pid);
		break;
	case CTA_PID_UPDATE:
		ret = pid_update(&s->pid, arg[0]);
		break;
	case CTA_PID_RAW_D:
		pid_set_raw_d(&s->pid, (uint8_t)arg[0]);
		break;
	case CTA_CTL_INIT:
		memset(&cc, 0, sizeof(cc));
		cc.duty_max_q15 = (int16_t)arg[1];
		cc.ff_speed_q15_per_m_s = arg[2];
		cc.ff_accel_q15_per_m_s2 = arg[3];
		cc.ff_angle_accel_q15_per_m_s2 = arg[4];
		for (uint8_t k = 0; k < CONTROL_N_PRESETS; k++) {
			cc.presets[k].p = (uint16_t)arg[5 + 3 * k];
			cc.presets[k].i = (uint16_t)arg[6 + 3 * k];
			cc.presets[k].d = (uint16_t)arg[7 + 3 * k];
		}
		cc.gain_slew_q15_per_s[0] = arg[14];
		cc.gain_slew_q15_per_s[1] = arg[14] / 3 + 1;
#if CONFIG_QUIET_SERVO
		cc.d_filter_ms = (uint8_t)arg[15];
		cc.d_lag_max_um = arg[16];
#endif
		ret = control_init(c, &cc, (uint16_t)arg[0]);
		break;
	case CTA_CTL_GAINS:
		g.p = (uint16_t)arg[0];
		g.i = (uint16_t)arg[1];
		g.d = (uint16_t)arg[2];
		control_set_gains(c, &g);
		break;
	case CTA_CTL_PRESET:
		/* SET_FILTRE: a preset's gains, -1 for no such preset */
		if ((uint8_t)arg[0] < CONTROL_N_PRESETS)
			control_set_gains(c, &c->cfg.presets[(uint8_t)arg[0]]);
		else
			ret = -1;
		break;
	case CTA_CTL_RESET:
		control_reset(c);
		break;
	case CTA_CTL_OFF:
		control_off(c);
		break;
	case CTA_CTL_UPDATE:
		axis_of(arg, &sd);
		axis_of(arg + 3, &sa);
		control_update(c, &sd, &sa, arg[6], arg[7]);
		break;
	case CTA_CTL_RAW_D:
		control_raw_d(c, (uint8_t)arg[0]);
		break;
	case CTA_ODO_ADVANCE: {
		struct odometry_arc a;
		struct odometry_position *o = &s->odo;

		o->x_um = (uint32_t)arg[4];
		o->y_um = (uint32_t)arg[5];
		o->x_frac = (uint16_t)arg[6];
		o->y_frac = (uint16_t)arg[7];
		o->trig_turn32 = (uint32_t)arg[8];
		o->trig_sin_q30 = arg[9];
		o->trig_cos_q30 = arg[10];
		odometry_arc_of(&a, arg[0], arg[1], arg[2], (uint32_t)arg[3]);
		odometry_advance(o, &a);
		break;
	}
	default:
		break;
	}
	memset(res, 0, CTA_N_RES * sizeof(*res));
	res[0] = ret;
	if (op >= CTA_PID_INIT && op <= CTA_PID_RAW_D) {
		pid_dump(&s->pid, res + 1);
	} else if (op >= CTA_CTL_INIT && op <= CTA_CTL_RAW_D) {
		res[1] = c->duty_q15[0];
		res[2] = c->duty_q15[1];
		res[3] = c->dist_err_um;
		res[4] = c->angle_err_um;
		res[5] = c->k_speed_q20;
		res[6] = c->k_accel_q20;
		res[7] = c->k_angle_accel_q20;
		res[8] = c->ff_narrow;
		res[9] = c->gains.p;
		res[10] = c->gains.i;
		res[11] = c->gains.d;
		res[12] = c->dist.kp_q12;
		res[13] = c->dist.kd_q12;
		res[14] = c->dist.fast.p_err_um;
		res[15] = c->dist.fast.d_err_um;
		pid_state(&c->dist, res + 16, res + 28);
		pid_state(&c->angle, res + 21, res + 30);
		res[26] = c->bump_q15[0];
		res[27] = c->bump_q15[1];
	} else if (op == CTA_ODO_ADVANCE) {
		res[1] = (int32_t)s->odo.x_um;
		res[2] = (int32_t)s->odo.y_um;
		res[3] = s->odo.x_frac;
		res[4] = s->odo.y_frac;
		res[5] = (int32_t)s->odo.trig_turn32;
		res[6] = s->odo.trig_sin_q30;
		res[7] = s->odo.trig_cos_q30;
	}
}
