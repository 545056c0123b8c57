/* The board: the servo's tick and the slow steps, each running its steps in order (board.h). */
#include "board.h"

#include <errno.h>
#include <stddef.h>

#include "field_defs.h"
#include "fixmath.h"
#include "protocol_defs.h"
#include "robot_defs.h"

typedef char board_field_baskets_fit[(FIELD_N_BASKETS <= ORDERS_MAX_BASKETS) ? 1 : -1];
typedef char board_field_lines_fit[(FIELD_N_LINES <= RECAL_MAX_LINES) ? 1 : -1];

#define UM_PER_MM 1000
#define POSITION_MAX_MM 32000 /* the range of POSITION's x and y (messages.toml) */
#define STATUS_END_BITS (STATUS_CHOC_PANIER | STATUS_CHOC_BORD | STATUS_PB_MOTEUR)

void board_default_config(struct board_config *c)
{
	/* Reference robot: 25 mm free wheels, 2000 counts/rev, 280 mm apart; drive wheels 160 mm
	 * apart; motors reaching ~1.64 m/s at full duty (Maxon RE25 24 V, 20.25:1, 32.5 mm
	 * wheels: ../shared/notes/physics.md). The ROBOT_ constants: robot/default.toml through
	 * robot/gen_robot.py (robot_defs.h). */
	const uint32_t um_per_count_q16 = ROBOT_ENC_UM_PER_COUNT_Q16; /* 78.540 um, * 2^16 */

	c->tick_hz = 1000;
	c->slow_shift = 0;    /* ports whose CPU is short run the slow steps at 125 Hz (3) */
	c->planner_ticks = 0; /* the slow steps in the tick itself */
	c->odometry.left_um_per_count_q16 = um_per_count_q16;
	c->odometry.right_um_per_count_q16 = um_per_count_q16;
	c->odometry.track_um = ROBOT_ENC_TRACK_UM;

	c->uncertainty.noise_left_mm2_per_m_q16 = (uint32_t)10 << 16; /* 0.1 mm^2/m, mid-range */
	c->uncertainty.noise_left_mm2_per_m_q16 /= 100;
	c->uncertainty.noise_right_mm2_per_m_q16 = c->uncertainty.noise_left_mm2_per_m_q16;
	c->uncertainty.track_um = ROBOT_ENC_TRACK_UM;
	c->uncertainty.ratio_error_ppm = 500; /* calibrated: 0.05 % */
	c->uncertainty.track_error_um = 100;  /* calibrated: 0.1 mm */
	c->uncertainty.scale_error_ppm = 500;
	c->uncertainty.k_q8 = 776; /* 3.03: 99 % */
	c->uncertainty.batch_ms = 10;
	c->uncertainty.rate_hz = 1000; /* the slow steps' rate: board_init() sets it */

	c->control.tick_hz = 1000;
	c->control.duty_max_q15 = 32767;
	c->control.ff_speed_q15_per_m_s = ROBOT_FF_SPEED_Q15_PER_M_S;
	c->control.ff_accel_q15_per_m_s2 = ROBOT_FF_ACCEL_Q15_PER_M_S2;
	c->control.ff_angle_accel_q15_per_m_s2 = ROBOT_FF_ANGLE_ACCEL_Q15_PER_M_S2;
	c->control.presets[FILTRE_STD] = (struct control_gains){205, 400, 160};
	c->control.presets[FILTRE_SOUPLE] = (struct control_gains){40, 0, 60};
	c->control.presets[FILTRE_RAIDE] = (struct control_gains){400, 1200, 250};

	c->faults.shock_basket_mask = 0x00; /* every shock sensor is on the border side */
	c->faults.following_max_um = 20000;
	c->faults.following_ms = 100;
	c->faults.current_max_ma = 6000;
	c->faults.current_ms = 50;
	c->faults.motor_encoders = 1;
	c->faults.motor_um_per_count_q16 = ROBOT_MOTOR_UM_PER_COUNT_Q16;
	c->faults.slip_max_um = 10000;
	c->faults.slip_window_ms = 128;
	c->faults.lost_min_um = 5000;
	c->faults.repeat_max = 3;
	c->faults.repeat_window_ms = 10000;
	c->faults.rate_hz = 1000; /* the slow steps' rate: board_init() sets it */

	c->orders.drive_track_um = ROBOT_DRIVE_TRACK_UM;
	c->orders.heading_window_turn32 = fx_deg_to_turn32(5);
	c->orders.freeze_radius_um = 30000;
	c->orders.arrive_window_um = 500;
	c->orders.arrive_speed_um_s = 5000;
	c->orders.settle_ms = 3;
	c->orders.aim_delay_steps = 0;
	c->orders.settle_timeout_ms = 1000;
	c->orders.push_speed_um_s = 150000;
	c->orders.push_max_um = 500000;
	c->orders.basket_contact_um = 150000;
	{
		/* the baskets of field/default.toml */
		static const struct orders_basket baskets[] = FIELD_BASKETS;

		c->orders.n_baskets = FIELD_N_BASKETS;
		for (uint8_t i = 0; i < FIELD_N_BASKETS; i++)
			c->orders.baskets[i] = baskets[i];
	}
	c->orders.tick_hz = 1000;
	c->orders.jerk_um_s3 = 0;
	c->orders.grip_um_s2 = ROBOT_GRIP_UM_S2;   /* mu 0.8 x 60 % of the weight x g */
	c->orders.rot_grip_q8 = ROBOT_ROT_GRIP_Q8; /* 4 x 0.10 kg m^2 / (8 kg x 0.160 m^2): 1.95 */

	/* Recalibration (docs/recalibration.md). The basket switch, a 1 mm-travel microswitch at
	 * the middle of the front edge, closes on a 125 mm circle within 16 mm of its centre. */
	c->orders.basket_lateral_um = 16000;
	c->orders.basket_bound_um = 1500;
	c->orders.borders = FIELD_BORDERS;
	c->orders.half_length_um = FIELD_LENGTH_UM / 2;
	c->orders.half_width_um = FIELD_WIDTH_UM / 2;
	c->orders.front_um = ROBOT_FRONT_UM;
	c->orders.front_shock_mask = 0x07; /* CAPTEUR_0..2 on the front edge */
	c->orders.border_speed_um_s = 100000;
	c->orders.border_extra_um = 60000;
	c->orders.border_block_um = 5000;
	c->orders.border_depth_um = 8000;
	c->orders.square_ms = 300;
	c->orders.backoff_um = 60000;
	c->orders.border_bound_um = 1000;
	c->orders.border_heading_bound_turn32 = fx_deg_to_turn32(1) / 4; /* 0.25 degree */
	{
		static const struct recal_line lines[] = FIELD_LINES;

		c->recal.n_lines = FIELD_N_LINES;
		for (uint8_t i = 0; i < FIELD_N_LINES; i++)
			c->recal.lines[i] = lines[i];
	}
	c->recal.n_sensors = 2; /* under the encoder axis, 40 mm either side of the middle */
	c->recal.sensors[0] = (struct recal_point){0, 40000};
	c->recal.sensors[1] = (struct recal_point){0, -40000};
	c->recal.max_angle_turn32 = fx_deg_to_turn32(30);
	c->recal.width_tol_um = 5000;
	c->recal.margin_um = 10000;
	c->recal.pair_window_um = 200000;
	c->recal.bound_um = 1000;
	c->recal.pair_bound_um = 300;
	c->recal.straight_turn32 = fx_deg_to_turn32(1) / 4; /* 0.25 degree */

	/* The specification's initial position "0, bout du terrain", angle 0: x 0 on the field's
	 * centre line, at the end of the field (its border at y -1050 mm, 2100 mm wide), the robot
	 * facing +X along that border. The reference robot's 250 x 300 mm outline sweeps a circle
	 * of 195 mm radius when it turns in place, so the start leaves it 200 mm from the border:
	 * its first GOTO begins with a turn. Teams set their own with the configuration or
	 * SET_NEW_POS. */
	c->start.x_um = 0;
	c->start.y_um = -850000;
	c->start.heading_turn32 = 0;
	/* The start pose is the reference of the estimate: no error at power-on (a team that
	 * places its robot by hand within, say, 2 mm and 1 degree sets these so that the radius
	 * covers the placement too). */
	c->start_radius_um = 0;
	c->start_heading_bound_turn32 = 0;
	/* Uncalibrated: wheel diameters within 0.3 % of the drawings each, the encoder track within
	 * 1 mm (sim/config.c's randomized robots; physics.md): a ratio within 0.6 %, a common scale
	 * within 0.3 %, and a track error with the scale's effect on turns (0.3 % of 280 mm) of
	 * 1.84 mm; with a margin. */
	c->uncalibrated.ratio_error_ppm = 7000;
	c->uncalibrated.track_error_um = 2000;
	c->uncalibrated.scale_error_ppm = 3500;
	/* A collision shoves the robot sideways while its wheels slide: friction decelerates that
	 * at mu g, 7.8 m/s^2 at mu 0.8 (sim/config.c); with a margin. The outline's farthest
	 * point, a corner of the 250 x 300 mm box, is 195 mm from the axis. */
	c->unseen.slide_decel_mm_s2 = 6000;
	c->unseen.reach_um = ROBOT_REACH_UM;
	/* A free wheel counts every 78.5 um: silent over 1 mm of its motor's travel, it slips,
	 * is lifted or is cut. */
	c->unseen.silent_min_um = 1000;
}

/* The angle axis [um of drive-wheel arc]: the exact sum of the heading steps times pi * drive
 * track, kept in [um * 2^32] (the product of a step and pi * track is exact; summing it is the
 * unwrapped heading times pi * track, bit for bit). Also the step's own arc, rounded, for the
 * measured turn rate. */
static void angle_axis_step(struct board *b, int32_t dtheta_turn32)
{
	uint32_t m = dtheta_turn32 >= 0 ? (uint32_t)dtheta_turn32
					: (uint32_t)0 - (uint32_t)dtheta_turn32;
	uint32_t lo, hi = fx_mul_u32_wide(m, (uint32_t)b->orders.pi_track_um, &lo);
	uint32_t old_lo = b->angle_lo;
	int32_t w;

	/* The step's arc rounded half away from zero. */
	b->arc_um = (int32_t)(hi + (lo >> 31));
	if (dtheta_turn32 < 0) {
		b->arc_um = -b->arc_um;
		b->angle_lo = old_lo - lo;
		b->angle_hi -= hi + (old_lo < lo);
	} else {
		b->angle_lo = old_lo + lo;
		b->angle_hi += hi + (b->angle_lo < old_lo);
	}
	/* Rounded half away from zero, like the rest of the core. */
	w = fx_int32_of(b->angle_hi);
	if (w >= 0 ? b->angle_lo >= 0x80000000u : b->angle_lo > 0x80000000u)
		w = w == INT32_MAX ? w : w + 1;
	b->angle_um = w;
}

/* Drive track / encoder track [2^-16], for comparing drive-wheel and free-wheel travel. */
static int32_t free_ratio_q16(const struct board_config *cfg, uint32_t track_um)
{
	return (int32_t)fx_div_round64((int64_t)cfg->orders.drive_track_um << 16, track_um);
}

/* a - b saturated, in 32 bits (a following error far out of range is still far out). */
static int32_t sub_sat(int32_t a, int32_t b)
{
	if (b < 0 && a > INT32_MAX + b)
		return INT32_MAX;
	if (b > 0 && a < INT32_MIN + b)
		return INT32_MIN;
	return a - b;
}

static void update_status(struct board *b);
static void publish(struct board *b);

/* The measure at the end of period p, whose sums and switches are in p. */
static void measure(const struct board *b, const struct board_snapshot *p, struct orders_measure *m)
{
	/* m->pose: the slow steps' (slow_steps(), step 0). */
	m->dist_um = p->dist_um;
	m->angle_um = p->angle_um;
	/* A period's steps are below 32.8 mm up to 3 m/s: 16 x 16-bit products. */
	m->dist_speed_um_s = fx_mul_s16(fx_sat16(p->ds_um), (int16_t)b->slow_hz);
	m->angle_speed_um_s = fx_mul_s16(fx_sat16(p->arc_um), (int16_t)b->slow_hz);
	m->basket_contact = p->in.basket;
	m->basket_shock = (p->in.shocks & b->cfg.faults.shock_basket_mask) != 0;
	m->shocks = p->in.shocks;
}

/* max(1, encoder track / drive track) [2^-16], rounded up: a free wheel travels that much more
 * than its drive wheel in a turn in place. */
static uint32_t turn_q16_of(const struct board_config *cfg, uint32_t track_um)
{
	uint32_t q = (uint32_t)(((uint64_t)track_um << 16) / cfg->orders.drive_track_um + 1);

	return q < 0x10000u ? 0x10000u : q;
}

/* A new period: its sums and switches from zero. */
static void period_clear(struct board_snapshot *p)
{
	p->ds_um = 0;
	p->arc_um = 0;
	p->dtheta_turn32 = 0;
	p->in.shocks = 0;
	p->in.basket = 0;
	p->encoder_fault = 0;
	p->wheels_replaced = 0;
	p->edges.rose = 0;
	p->edges.fell = 0;
}

int board_init(struct board *b, const struct board_config *cfg, const struct board_inputs *in)
{
	uint8_t shift = cfg->slow_shift;
	struct uncertainty_config uc = cfg->uncertainty;
	struct faults_config fc = cfg->faults;
	struct orders_config oc = cfg->orders;
	struct board_snapshot *p;

	if (cfg->tick_hz < 100 || cfg->tick_hz > 2000 || cfg->control.tick_hz != cfg->tick_hz ||
	    cfg->orders.tick_hz != cfg->tick_hz || shift > 3 || (cfg->tick_hz >> shift) < 100 ||
	    ((cfg->tick_hz >> shift) << shift) != cfg->tick_hz ||
	    cfg->planner_ticks > (1u << shift))
		return -1;
	b->cfg = *cfg;
	b->slow_hz = (uint16_t)(cfg->tick_hz >> shift);
	b->slow_mask = (uint8_t)((1u << shift) - 1u);
	/* The slow modules run at the slow steps' rate: their durations, in ms, in their updates.
	 */
	uc.rate_hz = b->slow_hz;
	uc.ratio_error_ppm = cfg->uncalibrated.ratio_error_ppm; /* until a calibration */
	uc.track_error_um = cfg->uncalibrated.track_error_um;
	uc.scale_error_ppm = cfg->uncalibrated.scale_error_ppm;
	fc.rate_hz = b->slow_hz;
	oc.tick_hz = b->slow_hz;
	{ /* half the larger free wheel's count [um, rounded up], a slow tick's worth */
		uint32_t q = cfg->odometry.left_um_per_count_q16;

		if (cfg->odometry.right_um_per_count_q16 > q)
			q = cfg->odometry.right_um_per_count_q16;
		oc.count_um_s = (int32_t)(((q >> 17) + 1u) * b->slow_hz);
	}
	proto_init(&b->proto);
	if (odometry_init(&b->odometry, &cfg->odometry, in->free_count[0], in->free_count[1]) ||
	    uncertainty_init(&b->uncertainty, &uc) || control_init(&b->control, &cfg->control) ||
	    faults_init(&b->faults, &fc, in->motor_count))
		return -1;
	b->soft = 0;
	b->gains = b->control.gains;
	odometry_set_pose(&b->odometry, &cfg->start);
	uncertainty_reset(&b->uncertainty, cfg->start_radius_um, cfg->start_heading_bound_turn32);
	b->angle_hi = 0;
	b->angle_lo = 0;
	b->angle_um = 0;
	b->arc_um = 0;
	b->free_ratio_q16 = free_ratio_q16(cfg, cfg->odometry.track_um);
	b->free_base[0] = in->free_count[0];
	b->free_base[1] = in->free_count[1];
	if (orders_init(&b->orders, &oc, odometry_get_distance_um(&b->odometry), 0) ||
	    recal_init(&b->recal, &cfg->recal))
		return -1;
	b->line_mask = (uint8_t)((1u << cfg->recal.n_sensors) - 1u);
	b->tick = 0;
	b->status = 0;
	b->timeout_ticks = 0;
	b->silent_ticks = 0;
	b->transactions_seen = b->proto.transactions;
	b->timed_out = 0;
	b->calibrated = 0;
	b->motor_base[0] = in->motor_count[0];
	b->motor_base[1] = in->motor_count[1];
	b->silent_counts[0] = 0;
	b->silent_counts[1] = 0;
	b->silent_widened[0] = 0;
	b->silent_widened[1] = 0;
	/* lost_min_um in motor counts, rounded down */
	b->silent_min_counts = cfg->faults.motor_um_per_count_q16 == 0
				       ? UINT32_MAX
				       : (uint32_t)(((uint64_t)(cfg->faults.lost_min_um > 0
									? cfg->faults.lost_min_um
									: 0)
						     << 16) /
						    cfg->faults.motor_um_per_count_q16);
	b->silent_turn_q16 = turn_q16_of(cfg, cfg->odometry.track_um);
	b->calibration = (struct board_calibration){0, 0, 0};
	b->last_out.duty_q15[0] = 0;
	b->last_out.duty_q15[1] = 0;
	/* The servo: holding where the orders start, nothing handed over, no period begun. */
	b->motors_off = 0;
	b->phase = 1;
	b->since_snapshot = 0;
	b->awaiting = 0;
	b->slow_overruns = 0;
	b->sp_dist = b->orders.sp_dist;
	b->sp_angle = b->orders.sp_angle;
	b->setpoints[0] = (struct board_setpoints){b->sp_dist, b->sp_angle, {0, 0, 0}, {0, 0, 0}};
	b->setpoints[1] = b->setpoints[0];
	b->setpoints_index = 0;
	b->handover = (struct board_handover){0};
	b->slow_due = 0;
	b->period_index = 0;
	period_clear(&b->period[0]);
	recal_sense_init(&b->lines, &b->period[0].edges, odometry_get_distance_um(&b->odometry));
	/* The reply snapshot of power-on, from a period of no time at all. */
	p = &b->period[1];
	p->in = *in;
	period_clear(p);
	p->in.shocks = in->shocks;
	p->in.basket = in->basket;
	p->dist_um = odometry_get_distance_um(&b->odometry);
	p->angle_um = b->angle_um;
	measure(b, p, &b->m);
	b->m.pose = odometry_get_pose(&b->odometry);
	p->tick = 0;
	p->dist_err_um = 0;
	p->angle_err_um = 0;
	p->duty_q15[0] = 0;
	p->duty_q15[1] = 0;
	update_status(b);
	publish(b);
	proto_flip(&b->proto);
	period_clear(p); /* the servo's next period */
	return 0;
}

/* A new order clears what the last one ended with. */
static void start_order(struct board *b)
{
	b->status &= (uint8_t)~STATUS_END_BITS;
	b->timed_out = 0;
	faults_order_started(&b->faults, b->shocks);
}

/* A coordinate corrected by SET_NEW_POS [um], kept within what POSITION reports: repeated
 * corrections cannot push the estimate out of the protocol's range (nor overflow it). */
static int32_t corrected_um(int32_t estimate_um, int32_t err_mm)
{
	int64_t v = (int64_t)estimate_um - (int64_t)err_mm * UM_PER_MM;
	const int64_t max_um = (int64_t)POSITION_MAX_MM * UM_PER_MM;

	return (int32_t)(v > max_um ? max_um : v < -max_um ? -max_um : v);
}

static void set_pose(struct board *b, const struct odometry_pose *p, struct orders_measure *m);

static void set_new_pos(struct board *b, const struct proto_msg *msg, struct orders_measure *m)
{
	struct odometry_pose p = m->pose;

	/* The master sends the estimate's error (estimate - truth): subtract it. */
	p.x_um = corrected_um(p.x_um, msg->arg[ARG_SET_NEW_POS_ERR_X_MM]);
	p.y_um = corrected_um(p.y_um, msg->arg[ARG_SET_NEW_POS_ERR_Y_MM]);
	p.heading_turn32 -= fx_deg_to_turn32(msg->arg[ARG_SET_NEW_POS_ERR_ANGLE_DEG]);
	/* Only the estimate moves, not the axes: the robot stays put, and a running GOTO re-aims
	 * from the corrected estimate at its next update (a frozen one keeps its targets). */
	set_pose(b, &p, m);
}

/* A nominal wheel factor times (1 + a / den) [um/count * 2^16], rounded. */
static int64_t scaled_factor(int64_t factor_q16, int32_t a, int32_t den)
{
	return fx_div_round64(factor_q16 * (den + a), den);
}

/* SET_ODOMETRIE: the calibrated wheel factors and encoder track, from the build's nominal
 * factors (cfg), so that the same message always gives the same configuration. The pose, the
 * error radius and the axes are kept; the next tick measures with the new values, and the error
 * radius uses the calibrated residual bounds. A result outside the odometry's ranges leaves the
 * configuration as it was (-EDOM). */
int board_set_calibration(struct board *b, const struct board_calibration *cal)
{
	const int32_t ppm = 1000000;
	struct odometry_config oc;
	struct uncertainty_config uc = b->uncertainty.cfg;
	int64_t left, right;
	int err;

	if (cal->ratio_ppm < -30000 || cal->ratio_ppm > 30000 || cal->scale_ppm < -30000 ||
	    cal->scale_ppm > 30000)
		return -EDOM;
	left = scaled_factor(b->cfg.odometry.left_um_per_count_q16, cal->scale_ppm, ppm);
	right = scaled_factor(b->cfg.odometry.right_um_per_count_q16, cal->scale_ppm, ppm);
	/* right * (1 + r/2), left * (1 - r/2): a right/left ratio of 1 + r + r^2/2 + ... */
	left = scaled_factor(left, -cal->ratio_ppm, 2 * ppm);
	right = scaled_factor(right, cal->ratio_ppm, 2 * ppm);
	if (left < 1 || right < 1 || left > ODOMETRY_UM_PER_COUNT_Q16_MAX ||
	    right > ODOMETRY_UM_PER_COUNT_Q16_MAX)
		return -EDOM;
	oc.left_um_per_count_q16 = (uint32_t)left;
	oc.right_um_per_count_q16 = (uint32_t)right;
	oc.track_um = (uint32_t)cal->track_10um * 10u;
	uc.track_um = oc.track_um;
	uc.ratio_error_ppm = b->cfg.uncertainty.ratio_error_ppm;
	uc.track_error_um = b->cfg.uncertainty.track_error_um;
	uc.scale_error_ppm = b->cfg.uncertainty.scale_error_ppm;
	err = odometry_check_config(&oc);
	if (err)
		return err;
	if (uncertainty_set_config(&b->uncertainty, &uc))
		return -EDOM;
	/* The odometry is the servo's: its tables are derived here, the servo copies them. */
	(void)odometry_derive_config(&oc, b->handover.odometry_wheels); /* checked above */
	b->handover.odometry_cfg = oc;
	b->handover.set_odometry = 1;
	b->free_ratio_q16 = free_ratio_q16(&b->cfg, oc.track_um);
	b->silent_turn_q16 = turn_q16_of(&b->cfg, oc.track_um);
	b->calibrated = 1;
	b->calibration = *cal;
	return 0;
}

static int set_odometrie(struct board *b, const struct proto_msg *msg)
{
	struct board_calibration cal;

	cal.ratio_ppm = msg->arg[ARG_SET_ODOMETRIE_RATIO_PPM];
	cal.scale_ppm = msg->arg[ARG_SET_ODOMETRIE_SCALE_PPM];
	cal.track_10um = (uint16_t)msg->arg[ARG_SET_ODOMETRIE_TRACK_10UM];
	return board_set_calibration(b, &cal);
}

/* New gains for the servo's PIDs (their integrals kept). */
static void set_gains(struct board *b, const struct control_gains *g)
{
	b->gains = *g;
	b->handover.gains = *g;
	b->handover.set_gains = 1;
}

/* SET_FILTRE(_RAW): during a border push the soft gains stay, and the master's come after it
 * (select_gains()); stiffer gains against the border would turn the contact into PB_MOTEUR. */
static void master_gains(struct board *b, const struct control_gains *g)
{
	if (b->soft)
		b->saved_gains = *g;
	else
		set_gains(b, g);
}

static void apply(struct board *b, const struct proto_msg *msg, struct orders_measure *m)
{
	const int32_t *a = msg->arg;
	struct control_gains g;

	if ((b->status & STATUS_PB_GRAVE) &&
	    proto_lookup(msg->designation)->kind == PROTO_KIND_ORDRE)
		return; /* raced the PB_GRAVE publication: refused like the protocol layer does */
	switch (msg->designation) {
	case PROTO_GOTO:
		start_order(b);
		orders_goto(&b->orders, m, a[ARG_GOTO_X_MM] * UM_PER_MM,
			    a[ARG_GOTO_Y_MM] * UM_PER_MM, (uint8_t)a[ARG_GOTO_OPTIONS]);
		break;
	case PROTO_GOTO_REVERSE:
		start_order(b);
		orders_goto_reverse(&b->orders, m, a[ARG_GOTO_REVERSE_DISTANCE_MM] * UM_PER_MM);
		break;
	case PROTO_GOTO_PANIER:
		start_order(b);
		orders_goto_panier(&b->orders, m,
				   fx_deg_to_turn32(a[ARG_GOTO_PANIER_ANGLE_2DEG] * 2));
		break;
	case PROTO_STOP:
		start_order(b);
		orders_stop(&b->orders);
		break;
	case PROTO_SET_VITESSE_TRAJ:
		orders_set_traj_limits(
			&b->orders, (uint8_t)a[ARG_SET_VITESSE_TRAJ_SPEED_CM_S],
			msg->n_args > 1 ? (uint8_t)a[ARG_SET_VITESSE_TRAJ_ACCEL_CM_S2] : 0);
		break;
	case PROTO_SET_VITESSE_ROT:
		orders_set_rot_limits(&b->orders, (uint8_t)a[ARG_SET_VITESSE_ROT_SPEED_CM_S],
				      msg->n_args > 1 ? (uint8_t)a[ARG_SET_VITESSE_ROT_ACCEL_CM_S2]
						      : 0);
		break;
	case PROTO_SET_FILTRE:
		if ((uint8_t)a[ARG_SET_FILTRE_PRESET] < CONTROL_N_PRESETS) /* by the table */
			master_gains(b, &b->cfg.control.presets[(uint8_t)a[ARG_SET_FILTRE_PRESET]]);
		break;
	case PROTO_SET_FILTRE_RAW:
		g.p = (uint16_t)a[ARG_SET_FILTRE_RAW_P];
		g.i = (uint16_t)a[ARG_SET_FILTRE_RAW_I];
		g.d = (uint16_t)a[ARG_SET_FILTRE_RAW_D];
		master_gains(b, &g);
		break;
	case PROTO_SET_NEW_POS:
		set_new_pos(b, msg, m);
		break;
	case PROTO_SET_TIMEOUT:
		/* Rounded up: the robot never stops before the time the master gave. */
		b->timeout_ticks =
			((uint32_t)a[ARG_SET_TIMEOUT_TIMEOUT_MS] * b->slow_hz + 999u) / 1000u;
		break;
	case PROTO_SET_ODOMETRIE:
		(void)set_odometrie(b, msg); /* in range by the message table; see set_odometrie */
		break;
	case PROTO_BOOTLOADER:
		/* The port leaves for its bootloader after this tick (docs/update.md); an order
		 * started since the protocol layer's check keeps the board here. */
		if (!orders_busy(&b->orders))
			b->boot_request = 1;
		break;
	default:
		break; /* ETAT messages never reach the queue */
	}
}

/* The larger magnitude. */
static int32_t max_mag(int32_t a, int32_t b)
{
	return (int32_t)(fx_mag32(a) > fx_mag32(b) ? fx_mag32(a) : fx_mag32(b));
}

/* A collision or a blocked robot (a shock, a motor problem): the robot may be shoved sideways,
 * which the free wheels do not measure, by up to what sliding from its speed takes,
 * v^2 / (2 slide_decel), v the speed of its farthest point (measured or commanded, the larger:
 * a blocked robot's set point still runs). The error radius widens by that. */
static void contact_slide(struct board *b, const struct orders_measure *m)
{
	const struct board_config *c = &b->cfg;
	uint64_t v = (uint64_t)max_mag(m->dist_speed_um_s, b->orders.sp_dist.vel_um_s);
	uint64_t w = (uint64_t)max_mag(m->angle_speed_um_s, b->orders.sp_angle.vel_um_s);
	uint64_t slide;

	if (c->unseen.slide_decel_mm_s2 == 0)
		return;
	/* the angle axis moves at the drive wheels' speed: a point reach_um from the axis moves
	 * reach / (drive track / 2) times as fast */
	v += (w * c->unseen.reach_um * 2 + c->orders.drive_track_um - 1) / c->orders.drive_track_um;
	if (v > 10000000u)
		v = 10000000u; /* 10 m/s */
	/* [um]: v^2 [um^2/s^2] / (2 a [mm/s^2] 1000) */
	slide = (v * v + 2000u * c->unseen.slide_decel_mm_s2 - 1) /
		(2000u * c->unseen.slide_decel_mm_s2);
	uncertainty_widen(&b->uncertainty, (uint32_t)(slide > 0xffffffffu ? 0xffffffffu : slide),
			  0);
}

/* Stop the running order at once; the status says why. */
static void react(struct board *b, uint8_t event, const struct orders_measure *m)
{
	static const uint8_t bits[] = {
		[FAULTS_SHOCK_BORD] = STATUS_CHOC_BORD,
		[FAULTS_SHOCK_PANIER] = STATUS_CHOC_PANIER,
		[FAULTS_MOTOR] = STATUS_PB_MOTEUR,
		[FAULTS_GRAVE] = STATUS_PB_GRAVE,
	};
	static const uint8_t reasons[] = {
		[FAULTS_SHOCK_BORD] = END_REASON_SHOCK,
		[FAULTS_SHOCK_PANIER] = END_REASON_SHOCK,
		[FAULTS_MOTOR] = END_REASON_MOTOR,
		[FAULTS_GRAVE] = END_REASON_FAULT,
	};

	if (event == FAULTS_NONE || ((b->status & STATUS_PB_GRAVE) && event == FAULTS_GRAVE))
		return;
	if (event == FAULTS_YIELD) {
		/* Idle and overloaded: hold where the robot now is, keeping the last end. */
		orders_abort(&b->orders, m, b->orders.end_reason);
		b->handover.reset = 1;
		b->handover.jump = 1;
		return;
	}
	contact_slide(b, m);
	if (event == FAULTS_SHOCK_BORD || event == FAULTS_SHOCK_PANIER)
		orders_shock(&b->orders, m, reasons[event]); /* a hold that gives way */
	else
		orders_abort(&b->orders, m, reasons[event]);
	b->handover.reset = 1;
	b->handover.jump = 1;
	b->status |= bits[event];
	b->timed_out = 0; /* a stop for the timeout ends on the fault instead */
}

/* A new estimate, at once: the pose is the slow steps' own (the servo only counts heading
 * changes, for the angle axis). */
static void set_pose(struct board *b, const struct odometry_pose *p, struct orders_measure *m)
{
	odometry_set_position(&b->odometry, p->x_um, p->y_um);
	m->pose = *p;
}

/* Line recalibration, while a GOTO with option bit 0 drives straight (recal.h). */
static void recal_lines(struct board *b, struct recal_edges *e, struct orders_measure *m)
{
	const struct orders *o = &b->orders;
	int enabled = o->designation == PROTO_GOTO && (o->options & ORDERS_OPT_LINE) &&
		      !o->border && o->state == ORDER_STATE_TRANSLATE;
	struct recal_fix fix;

	recal_take(&b->recal, e, enabled, &m->pose, m->dist_um, &b->uncertainty, &fix);
	if (!fix.what)
		return;
	set_pose(b, &fix.pose, m);
	if (fix.what & RECAL_FIX_HEADING)
		uncertainty_reset_heading(&b->uncertainty, fix.heading_bound_turn32);
	uncertainty_reset_along(&b->uncertainty, fix.normal_turn32, fix.bound_um);
}

/* A basket contact: the coordinate along the approach from the basket's geometry, the lateral
 * one clamped to the switch's window (orders_basket_pose()). */
static void recal_basket(struct board *b, struct orders_measure *m)
{
	const struct orders_config *oc = &b->cfg.orders;
	struct odometry_pose p;

	if (orders_basket_pose(&b->orders, &m->pose, &p) != 0)
		return;
	set_pose(b, &p, m);
	uncertainty_reset_along(&b->uncertainty, p.heading_turn32, oc->basket_bound_um);
	if (oc->basket_lateral_um > 0)
		uncertainty_cap_along(&b->uncertainty, p.heading_turn32 + ((uint32_t)1 << 30),
				      (uint32_t)oc->basket_lateral_um);
}

/* Squared up against a border: one coordinate and the heading (orders.c, border_recal()). */
static void recal_border(struct board *b, struct orders_measure *m)
{
	struct orders_recal r;

	if (!orders_take_recal(&b->orders, &r))
		return;
	set_pose(b, &r.pose, m);
	uncertainty_reset_heading(&b->uncertainty, b->cfg.orders.border_heading_bound_turn32);
	uncertainty_reset_axis(&b->uncertainty, r.axis ? UNCERTAINTY_AXIS_Y : UNCERTAINTY_AXIS_X,
			       b->cfg.orders.border_bound_um);
}

/* A border push runs on FILTRE_SOUPLE's gains; the gains in effect before come back after. */
static void select_gains(struct board *b)
{
	uint8_t soft = (uint8_t)orders_soft(&b->orders);

	if (soft == b->soft)
		return;
	if (soft) {
		b->saved_gains = b->gains;
		set_gains(b, &b->cfg.control.presets[FILTRE_SOUPLE]);
	} else {
		set_gains(b, &b->saved_gains);
	}
	b->handover.reset = 1;
	b->soft = soft;
}

/* An order ended by itself this tick. */
static void finish(struct board *b, uint8_t reason, struct orders_measure *m)
{
	if (reason == END_REASON_BORDER)
		b->status |= STATUS_CHOC_BORD;
	if (reason == END_REASON_NO_BASKET) /* not a motor fault: not counted towards PB_GRAVE */
		b->status |= STATUS_PB_MOTEUR;
	if (reason != END_REASON_BASKET)
		return;
	b->status |= STATUS_CHOC_PANIER;
	b->handover.reset = 1;
	recal_basket(b, m);
}

static void update_status(struct board *b)
{
	uint8_t s = b->status & (uint8_t)(STATUS_END_BITS | STATUS_PB_GRAVE);

	if (orders_busy(&b->orders)) {
		s |= STATUS_BUSY_TRAJET;
		if (b->orders.designation == PROTO_GOTO_PANIER)
			s |= STATUS_BUSY_GOTO_PANIER;
	}
	b->status = s;
}

/* round(um / 1000) saturated to 16 bits (ties away from zero). */
static int16_t mm_of(int32_t um)
{
	uint16_t q;

	if (um >= 32767500)
		return INT16_MAX;
	if (um <= -32768500)
		return INT16_MIN;
	q = fx_udiv1000(fx_mag32(um) + UM_PER_MM / 2u);
	return um >= 0 ? (int16_t)q : (int16_t) - (int32_t)q;
}

/* The heading in POSITION's 2-degree steps, rounded once from the heading itself (ties away
 * from zero): round(h 180 / 2^32) for h in [-2^31, 2^31), -90..90. */
static int8_t angle_2deg_of(uint32_t heading_turn32)
{
	int32_t h = (int32_t)heading_turn32;
	uint32_t lo, hi = fx_mul_u32_wide(fx_mag32(h), 180u, &lo);
	uint8_t q = (uint8_t)(hi + (lo >= 0x80000000u));

	return h >= 0 ? (int8_t)q : (int8_t) - (int16_t)q;
}

/* The reply snapshot of the last period, drafted (proto_draft()): the caller flips it public. */
static void publish(struct board *b)
{
	const struct board_snapshot *p = &b->period[b->period_index ^ 1u];
	const struct orders_measure *m = &b->m;
	struct proto_snapshot *s = proto_draft(&b->proto);
	int32_t cdeg = fx_turn32_to_cdeg(m->pose.heading_turn32);

	s->x_mm = mm_of(m->pose.x_um);
	s->y_mm = mm_of(m->pose.y_um);
	s->angle_2deg = angle_2deg_of(m->pose.heading_turn32); /* -90..90 */
	s->radius_mm = uncertainty_get_radius_mm(&b->uncertainty);
	s->status = b->status;
	s->sensors = p->in.shocks;
	s->calibrated = b->calibrated;
	s->debug.tick = p->tick;
	s->debug.heading_cdeg = (int16_t)cdeg;
	s->debug.speed_mm_s = mm_of(m->dist_speed_um_s);
	s->debug.turn_rate_cdeg_s = fx_sat16(fx_mul_s16(
		(int16_t)fx_turn32_to_cdeg((uint32_t)p->dtheta_turn32), (int16_t)b->slow_hz));
	s->debug.dist_err_um = fx_sat16(p->dist_err_um);
	s->debug.angle_err_um = fx_sat16(p->angle_err_um);
	s->debug.duty_left_q15 = p->duty_q15[0];
	s->debug.duty_right_q15 = p->duty_q15[1];
	s->debug.current_left_ma = p->in.current_ma[0];
	s->debug.current_right_ma = p->in.current_ma[1];
	s->debug.order_state = b->orders.state;
	s->debug.end_reason = (b->timed_out && !orders_busy(&b->orders)) ? END_REASON_TIMEOUT
									 : b->orders.end_reason;
}

/* (end - from) / 2^shift, rounded down: a tick's share of a period's change. */
static void sp_step(struct orders_axis *step, const struct orders_axis *from,
		    const struct orders_axis *end, uint8_t shift)
{
	step->pos_um = fx_floor_shr(end->pos_um - from->pos_um, shift);
	step->vel_um_s = fx_floor_shr(end->vel_um_s - from->vel_um_s, shift);
	step->acc_um_s2 = 0;
}

/* A free wheel that does not count while its motor turns (a wire cut, a wheel lifted, whether an
 * order runs or not) may be travelling unseen. Once its motor's net travel since the wheel last
 * counted passes unseen.silent_min_um, that travel, scaled to the encoder track for a turn,
 * widens the error radius as the wheel's unseen travel (uncertainty_widen()), and so does its
 * growth until the wheel counts again. Net: the holding loop's twitches cancel out. A drive
 * wheel slipping or spinning on its side of a blocked robot widens it too, which is only
 * conservative. */
static void silent_wheels(struct board *b, const int32_t travel_q16[2],
			  const uint16_t motor_count[2])
{
	const struct board_config *c = &b->cfg;

	for (uint8_t s = 0; s < 2; s++) {
		int16_t counts = (int16_t)(uint16_t)(motor_count[s] - b->motor_base[s]);
		uint32_t mag;

		b->motor_base[s] = motor_count[s];
		if (travel_q16[s] != 0) {
			b->silent_counts[s] = 0;
			b->silent_widened[s] = 0;
			continue;
		}
		if (counts == 0)
			continue;
		b->silent_counts[s] = fx_add_sat32(b->silent_counts[s], counts);
		mag = fx_mag32(b->silent_counts[s]);
		if (mag > b->silent_min_counts && mag > b->silent_widened[s]) {
			/* motor counts to um of free-wheel travel, scaled for a turn: a fault's
			 * path */
			uint64_t um = (((uint64_t)(mag - b->silent_widened[s]) *
						c->faults.motor_um_per_count_q16 +
					0xffffu) >>
				       16) * b->silent_turn_q16 +
				      0xffffu;

			um >>= 16;
			uncertainty_widen(&b->uncertainty, 0,
					  um > UINT32_MAX ? UINT32_MAX : (uint32_t)um);
			b->silent_widened[s] = mag;
		}
	}
}

/* The slow steps but the reply snapshot, on the last period (b->period[period_index ^ 1]). */
static void slow_steps(struct board *b)
{
	struct board_snapshot *p = &b->period[b->period_index ^ 1u];
	struct orders_measure *m = &b->m;
	struct faults_inputs fi;
	struct proto_msg msg;
	uint8_t reason, event;
	int32_t left_q16, right_q16; /* the free wheels' travels over the period */

	/* 0. The pose, along the period's travel as one arc ending at the period's heading change
	 * from the last pose. The travels from the counts, with the factors the period's ticks
	 * had. */
	{
		struct odometry_arc arc;
		uint32_t heading_turn32 = m->pose.heading_turn32 + (uint32_t)p->dtheta_turn32;
		const uint16_t *kl = p->wheels_replaced ? p->wheel_k[0] : b->odometry.left.k;
		const uint16_t *kr = p->wheels_replaced ? p->wheel_k[1] : b->odometry.right.k;

		left_q16 =
			odometry_travel_q16(kl, (int16_t)(p->in.free_count[0] - b->free_base[0]));
		right_q16 =
			odometry_travel_q16(kr, (int16_t)(p->in.free_count[1] - b->free_base[1]));
		b->free_base[0] = p->in.free_count[0];
		b->free_base[1] = p->in.free_count[1];
		odometry_arc_of(&arc, left_q16, right_q16, p->dtheta_turn32, heading_turn32);
		odometry_advance(&b->odometry, &arc);
		m->pose.x_um = odometry_round_um(b->odometry.x_um, b->odometry.x_frac, 0x8000u);
		m->pose.y_um = odometry_round_um(b->odometry.y_um, b->odometry.y_frac, 0x8000u);
		m->pose.heading_turn32 = heading_turn32;
		measure(b, p, m);
	}

	/* 1. Error radius, from the period's travel, and what the free wheels may not have seen. */
	uncertainty_update(&b->uncertainty, left_q16, right_q16, m->pose.heading_turn32);
	{
		int32_t travel_q16[2];

		travel_q16[0] = left_q16;
		travel_q16[1] = right_q16;
		silent_wheels(b, travel_q16, p->in.motor_count);
	}
	uncertainty_advance(&b->uncertainty, b->slow_mask); /* its stages as fast in time */

	/* 2. The switches; line crossings. */
	b->shocks = p->in.shocks;
	recal_lines(b, &p->edges, m);

	/* 3. Messages from the master, in the order they arrived, until the period's end. */
	while (b->proto.tail != p->msg_head && proto_poll(&b->proto, &msg))
		apply(b, &msg, m);

	/* 3b. The master's silence (SET_TIMEOUT): any transaction that addresses the board, even
	 * a poll or a rejected write, shows the master alive. When it has been silent for the
	 * timeout, the running order stops at the current limits, as by STOP. */
	if (p->transactions != b->transactions_seen) {
		b->transactions_seen = p->transactions;
		b->silent_ticks = 0;
	} else if (b->silent_ticks < UINT32_MAX) {
		b->silent_ticks++;
	}
	if (b->timeout_ticks && b->silent_ticks >= b->timeout_ticks && orders_busy(&b->orders) &&
	    b->orders.state != ORDER_STATE_STOPPING) {
		orders_stop(&b->orders);
		b->timed_out = 1;
	}

	/* 4. Stop conditions: shocks, motor problems, unrecoverable faults. */
	/* Pushing a basket closes the front bumper with the basket switch: the expected contact. */
	/* Against the border, the front switches are the expected contact. */
	fi.shocks = (b->orders.state == ORDER_STATE_PUSH && p->in.basket) ? 0 : p->in.shocks;
	fi.shocks &= (uint8_t)~orders_expected_shocks(&b->orders);
	fi.current_ma[0] = p->in.current_ma[0];
	fi.current_ma[1] = p->in.current_ma[1];
	fi.motor_count[0] = p->in.motor_count[0];
	fi.motor_count[1] = p->in.motor_count[1];
	fi.free_step_q16[0] = left_q16;
	fi.free_step_q16[1] = right_q16;
	fi.free_ratio_q16 = b->free_ratio_q16;
	fi.dist_err_um = sub_sat(p->sp_dist_um, m->dist_um);
	fi.angle_err_um = sub_sat(p->sp_angle_um, m->angle_um);
	fi.moving = (uint8_t)orders_busy(&b->orders);
	fi.pushing = b->orders.state == ORDER_STATE_PUSH || b->orders.state == ORDER_STATE_SQUARE;
	event = faults_check(&b->faults, &fi);
	react(b, p->encoder_fault ? FAULTS_GRAVE : event, m);

	/* 5. Orders -> profiles -> set points of both axes; the contact recalibrations. */
	reason = orders_update(&b->orders, m);
	if (b->orders.gave_way) { /* the hold after a shock moved away from the obstacle */
		b->orders.gave_way = 0;
		b->handover.reset = 1;
	}
	recal_border(b, m);
	finish(b, reason, m);
	select_gains(b);
	update_status(b);

	/* 6. After a motor problem the motors stay off until the next order: holding the position
	 * would drive the same stalled, slipping or overloaded motor again. Nothing holds the
	 * robot then, so the set points follow it and the next order starts from where it is. */
	b->handover.motors_off = (b->status & (STATUS_PB_GRAVE | STATUS_PB_MOTEUR)) != 0;
	if (b->handover.motors_off) {
		orders_abort(&b->orders, m, b->orders.end_reason);
		b->handover.jump = 1;
	}
	{
		const struct board_setpoints *now = &b->setpoints[b->setpoints_index];
		struct board_setpoints *next = &b->setpoints[b->setpoints_index ^ 1u];

		next->dist = b->orders.sp_dist;
		next->angle = b->orders.sp_angle;
		/* From the last ones, where the servo is at the hand-over (it gets there at the
		 * period's last tick, or at once by a jump). */
		sp_step(&next->dist_step, &now->dist, &next->dist, b->cfg.slow_shift);
		sp_step(&next->angle_step, &now->angle, &next->angle, b->cfg.slow_shift);
	}
}

/* The compiler may not move memory accesses across it: the snapshot is read after slow_due said
 * it is there, and the hand-over is complete in memory before slow_due says so, since the
 * servo's interrupt may come right after. */
#ifdef __GNUC__
#define BOARD_BARRIER() __asm__ __volatile__("" ::: "memory")
#else
#define BOARD_BARRIER() ((void)0)
#endif

void board_slow(struct board *b)
{
	BOARD_BARRIER();
	slow_steps(b);
	publish(b);
	b->handover.publish = 1; /* made public at the hand-over, with the servo's new state */
	period_clear(&b->period[b->period_index ^ 1u]); /* the servo's next period */
	BOARD_BARRIER();
	b->slow_due = 0;
}

/* One axis's set point a tick further towards the handed-over one (reached at the period's
 * last tick). Its acceleration is the handed-over one from the hand-over on (take_handover()). */
static void sp_advance(struct orders_axis *sp, const struct orders_axis *step,
		       const struct orders_axis *end, int last)
{
	if (last) { /* the acceleration stays the handed-over one */
		sp->pos_um = end->pos_um;
		sp->vel_um_s = end->vel_um_s;
		return;
	}
	sp->pos_um += step->pos_um;
	sp->vel_um_s += step->vel_um_s;
}

/* New wheel factors (SET_ODOMETRIE), at the end of the period p, after its travel: its counts
 * are worth the old factors, which it keeps. */
static void take_wheels(struct board *b, struct board_snapshot *p)
{
	struct board_handover *h = &b->handover;

	p->wheels_replaced = 1;
	p->wheel_k[0][0] = b->odometry.left.k[0];
	p->wheel_k[0][1] = b->odometry.left.k[1];
	p->wheel_k[1][0] = b->odometry.right.k[0];
	p->wheel_k[1][1] = b->odometry.right.k[1];
	odometry_install_config(&b->odometry, &h->odometry_cfg, h->odometry_wheels);
	h->set_odometry = 0;
}

/* The slow steps' results, taken by the servo: set points, gains, the reply's flip. */
static void take_handover(struct board *b)
{
	struct board_handover *h = &b->handover;

	if (h->set_gains) {
		control_set_gains(&b->control, &h->gains);
		h->set_gains = 0;
	}
	if (h->reset) {
		control_reset(&b->control);
		h->reset = 0;
	}
	b->motors_off = h->motors_off;
	if (h->publish) {
		proto_flip(&b->proto);
		h->publish = 0;
	}
	/* The set points go from where they are to the new ones over the next period; the
	 * acceleration is the new one at once (the control's feed-forward then computes its term
	 * once a period). */
	b->setpoints_index ^= 1u;
	b->phase = 0;
	b->sp_dist.acc_um_s2 = b->setpoints[b->setpoints_index].dist.acc_um_s2;
	b->sp_angle.acc_um_s2 = b->setpoints[b->setpoints_index].angle.acc_um_s2;
	if (h->jump) {
		b->sp_dist = b->setpoints[b->setpoints_index].dist;
		b->sp_angle = b->setpoints[b->setpoints_index].angle;
		b->phase = (uint8_t)(1u << b->cfg.slow_shift);
		h->jump = 0;
	}
}

/* The period's end: what the slow steps work on, and a new period. */
static void take_snapshot(struct board *b, const struct board_inputs *in, int32_t dist_um)
{
	struct board_snapshot *p = &b->period[b->period_index];

	/* The tick's inputs but the switches, which are the period's. */
	p->in.free_count[0] = in->free_count[0];
	p->in.free_count[1] = in->free_count[1];
	p->in.motor_count[0] = in->motor_count[0];
	p->in.motor_count[1] = in->motor_count[1];
	p->in.current_ma[0] = in->current_ma[0];
	p->in.current_ma[1] = in->current_ma[1];
	p->in.lines = in->lines;
	p->dist_um = dist_um;
	p->angle_um = b->angle_um;
	p->sp_dist_um = b->sp_dist.pos_um;
	p->sp_angle_um = b->sp_angle.pos_um;
	p->msg_head = b->proto.head;
	p->transactions = b->proto.transactions;
	/* The next period was cleared by the slow steps, done with it (board_slow()). */
	b->period_index ^= 1u;
	b->period[b->period_index].edges.on = p->edges.on;
}

/* The control's side of the snapshot: the last tick's (the snapshot is taken before this one's
 * control). */
static void snapshot_control(struct board *b, struct board_snapshot *p)
{
	p->tick = b->tick;
	p->dist_err_um = b->control.dist_err_um;
	p->angle_err_um = b->control.angle_err_um;
	p->duty_q15[0] = b->control.duty_q15[0];
	p->duty_q15[1] = b->control.duty_q15[1];
}

void board_tick(struct board *b, const struct board_inputs *in, struct board_outputs *out)
{
	struct board_snapshot *p = &b->period[b->period_index];
	const struct odometry_step *step;
	uint8_t period_ends = (b->tick & b->slow_mask) == 0;
	int32_t dist_um;

	/* 1. Encoders -> odometry (a wheel that jumps more than a tick can travel is a fault). */
	if (odometry_count(&b->odometry, in->free_count[0], in->free_count[1]) != 0)
		p->encoder_fault = 1;
	step = &b->odometry.step;
	dist_um = odometry_get_distance_um(&b->odometry); /* the tick's distance axis */
	/* The angle axis only moves with the heading. */
	if (step->dtheta_turn32 != 0)
		angle_axis_step(b, step->dtheta_turn32);
	else
		b->arc_um = 0;

	/* 2. The period's sums for the slow steps; the switches, kept if pressed at any tick; the
	 * line sensors' edges, timed at their tick. */
	p->ds_um = (int32_t)((uint32_t)p->ds_um + (uint32_t)step->ds_um);
	p->arc_um = (int32_t)((uint32_t)p->arc_um + (uint32_t)b->arc_um);
	p->dtheta_turn32 = (int32_t)((uint32_t)p->dtheta_turn32 + (uint32_t)step->dtheta_turn32);
	p->in.shocks |= in->shocks;
	p->in.basket |= in->basket;
	recal_sense(&b->lines, &p->edges, in->lines & b->line_mask, dist_um);

	/* 3. At the period's end: new wheel factors (after its travel), then the snapshot the slow
	 * steps work on next, unless the last one's results are not taken yet (the period goes
	 * on). With planner_ticks 0 they run here, in this tick. */
	if (b->since_snapshot < UINT8_MAX)
		b->since_snapshot++;
	if (period_ends && !b->slow_due && b->handover.set_odometry)
		take_wheels(b, p);
	if (period_ends && !b->slow_due && !b->awaiting) {
		snapshot_control(b, p);
		take_snapshot(b, in, dist_um);
		b->since_snapshot = 0;
		b->awaiting = 1;
		b->slow_due = 1;
		if (b->cfg.planner_ticks == 0)
			board_slow(b);
	}

	/* 4. The slow steps' results, planner_ticks after the snapshot they worked on (later if
	 * they still run: an overrun). */
	if (b->awaiting && b->since_snapshot >= b->cfg.planner_ticks) {
		if (!b->slow_due) {
			take_handover(b);
			b->awaiting = 0;
		} else if (b->since_snapshot == b->cfg.planner_ticks) {
			b->slow_overruns++;
		}
	}

	/* 5. The set points of this tick, a step towards the handed-over ones. */
	if (b->phase <= b->slow_mask) { /* phase < 2^shift */
		const struct board_setpoints *s = &b->setpoints[b->setpoints_index];
		uint8_t last = b->phase == b->slow_mask;

		b->phase++;
		sp_advance(&b->sp_dist, &s->dist_step, &s->dist, last);
		sp_advance(&b->sp_angle, &s->angle_step, &s->angle, last);
	}

	/* 6. Control: feed-forward + PID on both axes, mixed into the motor duties; none after a
	 * motor problem (slow_steps()). */
	if (b->motors_off)
		control_off(&b->control);
	else
		control_update(&b->control, &b->sp_dist, &b->sp_angle, dist_um, b->angle_um);

	/* 7. Outputs. */
	out->duty_q15[0] = b->control.duty_q15[0];
	out->duty_q15[1] = b->control.duty_q15[1];
	b->last_out = *out;
	b->tick++;
}
