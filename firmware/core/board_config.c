/* The board's configuration: the reference robot's defaults (board_default_config()), and the
 * checks and derived values of board_init(). */
#include <stddef.h>

#include "board_parts.h"
#include "field_defs.h"
#include "fixmath.h"
#include "protocol_defs.h"
#include "robot_defs.h"

typedef char board_field_baskets_fit[(FIELD_N_BASKETS <= ORDERS_MAX_BASKETS) ? 1 : -1];
typedef char board_field_lines_fit[(FIELD_N_LINES <= RECAL_MAX_LINES) ? 1 : -1];

/* The error radius: the free wheels' noise, the model's residual bounds, 99 %. */
static void default_uncertainty(struct board_config *c)
{
	c->uncertainty.noise_left_mm2_per_m_q16 = (uint32_t)10 << 16; /* 0.1 mm^2/m, mid-range */
	c->uncertainty.noise_left_mm2_per_m_q16 /= 100;
	c->uncertainty.noise_right_mm2_per_m_q16 = c->uncertainty.noise_left_mm2_per_m_q16;
	c->uncertainty.k_q8 = 776; /* 3.03: 99 % */
	c->uncertainty.batch_ms = 10;
	c->calibrated.ratio_error_ppm = 500; /* calibrated: 0.05 % */
	c->calibrated.track_error_um = 100;  /* calibrated: 0.1 mm */
	c->calibrated.scale_error_ppm = 500;
	/* Uncalibrated: wheel diameters within 0.3 % of the drawings each, the encoder track within
	 * 1 mm (sim/config.c's randomized robots; physics.md): a ratio within 0.6 %, a common scale
	 * within 0.3 %, and a track error with the scale's effect on turns (0.3 % of 280 mm) of
	 * 1.84 mm; with a margin. */
	c->uncalibrated.ratio_error_ppm = 7000;
	c->uncalibrated.track_error_um = 2000;
	c->uncalibrated.scale_error_ppm = 3500;
}

/* [ms] see default_control() */
#define GAIN_SLEW_MS 50
/* [ms] the PIDs' derivative's low-pass and [um] its largest lag (docs/control.md "PID"): a
 * free-wheel count is 78.5 um, half of it on either axis */
#define D_FILTER_MS 16
#define D_LAG_MAX_UM 320

static void default_control(struct board_config *c)
{
	c->control.duty_max_q15 = 32767;
	c->control.ff_speed_q15_per_m_s = ROBOT_FF_SPEED_Q15_PER_M_S;
	c->control.ff_accel_q15_per_m_s2 = ROBOT_FF_ACCEL_Q15_PER_M_S2;
	c->control.ff_angle_accel_q15_per_m_s2 = ROBOT_FF_ANGLE_ACCEL_Q15_PER_M_S2;
	/* A change of gains takes in its step at the duty of the grip's acceleration every
	 * GAIN_SLEW_MS: the feed-forward's duty of grip_um_s2 along the distance, and of
	 * grip_um_s2 / rot_grip of wheel arc turning (orders.h, "a + k a' <= grip"). */
	c->control.gain_slew_q15_per_s[0] = (int32_t)((int64_t)ROBOT_FF_ACCEL_Q15_PER_M_S2 *
						      ROBOT_GRIP_UM_S2 / GAIN_SLEW_MS / 1000);
	c->control.gain_slew_q15_per_s[1] =
		(int32_t)((int64_t)ROBOT_FF_ANGLE_ACCEL_Q15_PER_M_S2 * ROBOT_GRIP_UM_S2 * 256 /
			  ROBOT_ROT_GRIP_Q8 / GAIN_SLEW_MS / 1000);
#if CONFIG_QUIET_SERVO
	c->control.d_filter_ms = D_FILTER_MS;
	c->control.d_lag_max_um = D_LAG_MAX_UM;
#endif
	c->control.presets[FILTRE_STD] = (struct control_gains){205, 400, 160};
	c->control.presets[FILTRE_SOUPLE] = (struct control_gains){40, 0, 60};
	c->control.presets[FILTRE_RAIDE] = (struct control_gains){400, 1200, 250};
}

static void default_faults(struct board_config *c)
{
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
}

/* The orders: arrival, settle, the basket, the grip. */
static void default_orders(struct board_config *c)
{
	/* the baskets of field/default.toml */
	static const struct orders_basket baskets[] = FIELD_BASKETS;

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
	c->orders.n_baskets = FIELD_N_BASKETS;
	for (uint8_t i = 0; i < FIELD_N_BASKETS; i++)
		c->orders.baskets[i] = baskets[i];
	c->orders.jerk_um_s3 = 0;
	c->orders.grip_um_s2 = ROBOT_GRIP_UM_S2;   /* mu 0.8 x 60 % of the weight x g */
	c->orders.rot_grip_q8 = ROBOT_ROT_GRIP_Q8; /* 4 x 0.10 kg m^2 / (8 kg x 0.160 m^2): 1.95 */
}

/* Recalibration (docs/recalibration.md): the basket, the borders, the lines. */
static void default_recal(struct board_config *c)
{
	static const struct recal_line lines[] = FIELD_LINES;

	/* The basket switch, a 1 mm-travel microswitch at the middle of the front edge, closes on
	 * a 125 mm circle within 16 mm of its centre. */
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
	c->recal.n_lines = FIELD_N_LINES;
	for (uint8_t i = 0; i < FIELD_N_LINES; i++)
		c->recal.lines[i] = lines[i];
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
}

/* Where the robot starts, and what the odometry may not see. */
static void default_start(struct board_config *c)
{
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
	/* A collision shoves the robot sideways while its wheels slide: friction decelerates that
	 * at mu g, 7.8 m/s^2 at mu 0.8 (sim/config.c); with a margin. The outline's farthest
	 * point, a corner of the 250 x 300 mm box, is 195 mm from the axis. */
	c->unseen.slide_decel_mm_s2 = 6000;
	c->unseen.reach_um = ROBOT_REACH_UM;
	/* A free wheel counts every 78.5 um: silent over 1 mm of its motor's travel, it slips,
	 * is lifted or is cut. */
	c->unseen.silent_min_um = 1000;
}

void board_default_config(struct board_config *c)
{
	/* Reference robot: 25 mm free wheels, 2000 counts/rev, 280 mm apart; drive wheels 160 mm
	 * apart; motors reaching ~1.64 m/s at full duty (Maxon RE25 24 V, 20.25:1, 32.5 mm
	 * wheels: ../shared/notes/physics.md). The ROBOT_ constants: robot/default.toml through
	 * robot/gen_robot.py (robot_defs.h). */
	const uint32_t um_per_count_q16 = ROBOT_ENC_UM_PER_COUNT_Q16; /* 78.540 um, * 2^16 */

	c->tick_hz = 1000;
	c->slow_shift = 0;    /* ports whose CPU is short run the planner at 125 Hz (3) */
	c->planner_ticks = 0; /* the planner in the tick itself */
	c->odometry.left_um_per_count_q16 = um_per_count_q16;
	c->odometry.right_um_per_count_q16 = um_per_count_q16;
	c->odometry.track_um = ROBOT_ENC_TRACK_UM;
	default_uncertainty(c);
	default_control(c);
	default_faults(c);
	default_orders(c);
	default_recal(c);
	default_start(c);
}

int board_config_check(const struct board_config *cfg)
{
	uint8_t shift = cfg->slow_shift;

	if (cfg->tick_hz < 100 || cfg->tick_hz > 2000 || shift > 3 ||
	    (cfg->tick_hz >> shift) < 100 || ((cfg->tick_hz >> shift) << shift) != cfg->tick_hz ||
	    cfg->planner_ticks > (1u << shift))
		return -1;
	return 0;
}

int32_t board_free_ratio_q16(const struct board_config *cfg, uint32_t track_um)
{
	return (int32_t)fx_div_round64((int64_t)cfg->orders.drive_track_um << 16, track_um);
}

uint32_t board_turn_q16(const struct board_config *cfg, uint32_t track_um)
{
	uint32_t q = (uint32_t)(((uint64_t)track_um << 16) / cfg->orders.drive_track_um + 1);

	return q < 0x10000u ? 0x10000u : q;
}
