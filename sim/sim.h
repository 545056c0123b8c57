/* Public API of the robot and field physics simulator (C99, double precision, deterministic).
 *
 * What is simulated (defaults and sources in docs/physics-sources.md):
 *   - a differential-drive robot: two DC motors (Maxon RE25 24 V by default) with a gearbox,
 *     driving two wheels whose contact force on the table is limited by friction (mu N, friction
 *     circle), so the wheels slip when the motors ask for more than the table can give;
 *   - two free (non-driven) encoder wheels with diameter mismatch, track error, random noise
 *     (variance k |ds|) and quantisation to counts; encoders on the motor shafts; motor currents;
 *   - the field: borders, baskets (circles or axis-aligned boxes) that stop the robot outline,
 *     lines on the floor; shock switches, a basket contact switch and line sensors.
 *
 * Numerical method (details in robot.c): fixed substep (100 us by default, i.e. 10 substeps per
 * 1 kHz control tick), semi-implicit (symplectic) Euler for the body and the wheels, exact
 * exponential update of the motor current (so the 0.1 ms L/R time constant is kept and stable at
 * any substep), a linearly implicit tyre force, and penalty spring-dampers for the walls.
 * Away from every contact, a whole control tick may be one substep of coarse_substep_ns (off by
 * default here; 1 ms by default in the Python Simulator): the wall springs, the only part that
 * needs 100 us, are not integrated then; nor while a tyre nears its grip, nor for 0.5 s after a
 * contact (the stop and the rebound), where the 100 us substep resolves the tyres' stick and
 * slide (robot.c, sim_advance_ns()).
 *
 * Conventions:
 *   - Field frame: origin at the centre of the table, X along the long side (3000 mm), Y along the
 *     short side (2100 mm), headings counter-clockwise from +X, in radians.
 *   - Robot frame: origin at the midpoint of the drive wheel axis, x forward, y to the left.
 *     Index 0 is the left wheel/motor/encoder (SIM_LEFT), 1 the right one (SIM_RIGHT).
 *   - Positive duty on both motors drives the robot forward; forward motion counts up on every
 *     encoder.
 *   - Lengths in mm and angles in rad at the API, SI units inside.
 *
 * Determinism: the same configuration, field, seed and sequence of calls give the same bits on
 * the same machine and build (no global state, no clock, no threads; the library is built with
 * -ffp-contract=off). Results may differ in the last bits between C libraries (sin, cos, exp).
 *
 * Thread safety: none needed; instances are independent. Nothing here is meant for an interrupt.
 */
#ifndef ASSERV_SIM_H
#define ASSERV_SIM_H

#include <stdbool.h>
#include <stdint.h>

#include "rng.h"

#define SIM_LEFT 0
#define SIM_RIGHT 1

#define SIM_MAX_SHOCK 8
#define SIM_MAX_LINE_SENSORS 4
#define SIM_MAX_OBSTACLES 16
#define SIM_MAX_LINES 32
#define SIM_MAX_OPPONENTS 4
#define SIM_MAX_PATH 16

/* Returned (negated) by sim_init() for an invalid or numerically unstable configuration. */
#define SIM_EINVAL 22

/* ---------------------------------------------------------------------------------------------
 * Field
 */

enum sim_shape {
	SIM_SHAPE_CIRCLE = 0, /* uses radius_mm */
	SIM_SHAPE_BOX = 1,    /* uses half_x_mm and half_y_mm, turned by heading_rad */
};

enum sim_obstacle_kind {
	SIM_OBSTACLE_BASKET = 0, /* closes the basket switch and the shock switches */
	SIM_OBSTACLE_OTHER = 1,  /* closes the shock switches only */
};

struct sim_obstacle {
	uint8_t shape; /* enum sim_shape */
	uint8_t kind;  /* enum sim_obstacle_kind */
	double x_mm;   /* centre, field frame */
	double y_mm;
	double radius_mm;
	double half_x_mm;
	double half_y_mm;
	double heading_rad; /* a box's x axis from the field's X, counter-clockwise; 0: aligned */
};

/* A painted line: the segment (x0, y0)-(x1, y1) widened by width_mm (rounded ends). */
struct sim_line {
	double x0_mm;
	double y0_mm;
	double x1_mm;
	double y1_mm;
	double width_mm;
};

struct sim_field {
	double length_mm; /* along X, default 3000; the borders are at x = +/- length_mm / 2 */
	double width_mm;  /* along Y, default 2100; the borders are at y = +/- width_mm / 2 */
	bool borders;     /* false: an endless floor (for tests that need room) */
	uint8_t obstacle_count;
	struct sim_obstacle obstacles[SIM_MAX_OBSTACLES];
	uint8_t line_count;
	struct sim_line lines[SIM_MAX_LINES];
};

/* Fills f with the 3000 x 2100 mm table, its borders, two example baskets (circles of radius
 * 125 mm at (-1200, 750) and (1200, -750)) and four 20 mm lines (x = -750, x = 0, x = 750, y = 0).
 */
void sim_field_defaults(struct sim_field *f);

/* ---------------------------------------------------------------------------------------------
 * Configuration (settings that do not change during a run)
 */

struct sim_point {
	double x_mm; /* robot frame */
	double y_mm;
};

struct sim_pose {
	double x_mm; /* field frame */
	double y_mm;
	double heading_rad; /* -pi..pi when read back */
};

struct sim_motor_config {
	double kv_rpm_per_V;   /* speed constant, default 407 */
	double kt_mNm_per_A;   /* torque constant, default 23.4 */
	double resistance_ohm; /* terminal resistance, default 2.32 */
	double inductance_mH;  /* default 0.24; 0 makes the current follow the voltage at once */
	double rotor_inertia_g_cm2; /* default 10.3 */
	double friction_mNm;        /* Coulomb friction at the motor shaft, default 0.7 (GUESS) */
	double gear_ratio;          /* motor turns per wheel turn, default 20.25 */
	double gear_efficiency;     /* 0..1, default 0.75, scales the torque passed to the wheel */
	uint32_t encoder_cpr;       /* motor encoder counts per motor turn after x4, default 2048 */
};

struct sim_config {
	/* Body and drive */
	double mass_kg;            /* default 8 */
	double yaw_inertia_kg_m2;  /* default 0.10: an 8 kg uniform box of 250 x 300 mm */
	double drive_weight_share; /* share of the weight on the driven wheels, 0..1, default 0.6 */
	double friction_coeff;     /* mu of the drive wheels on the table, default 0.8 */
	double tyre_stiffness_N_m; /* tangential stiffness of the tread before it slides,
				    * default 1e5 (0.2 mm at full grip) (GUESS) */
	double slip_damping_N_s_m; /* tyre force per slip speed, default 3000 (GUESS); the tyre
				    * force k z + c s is capped at mu N (z: deflection, s: slip
				    * speed) */
	double drive_radius_mm;    /* default 32.5 */
	double drive_track_mm;     /* distance between the drive wheels, default 160 */
	double wheel_inertia_g_cm2; /* one drive wheel without the motor, default 200 (GUESS) */
	struct sim_motor_config motor;
	double battery_V; /* initial battery voltage, default 24 */
	bool lifted;      /* robot on a stand: the wheels turn freely, the body stays */

	/* Free encoder wheels. The nominal values are what the firmware believes; the true wheels
	 * have radius enc_radius_mm * (1 + enc_radius_error[i]) and sit at
	 * y = +/- (enc_track_mm + enc_track_error_mm) / 2, x = enc_offset_x_mm. */
	double enc_radius_mm;          /* default 25 */
	double enc_track_mm;           /* default 280 */
	double enc_offset_x_mm;        /* encoder axis ahead of the drive axis, default 0 */
	double enc_radius_error[2];    /* relative, e.g. 0.003 = +0.3 %, default 0 */
	double enc_track_error_mm;     /* default 0 */
	double enc_noise_mm2_per_m[2]; /* variance k of the random error per metre, default 0 */
	uint32_t enc_cpr;              /* counts per wheel turn after x4, default 2000 */

	/* Outline (a rectangle) and sensors, robot frame */
	double outline_length_mm;              /* along x, default 250 */
	double outline_width_mm;               /* along y, default 300 */
	double outline_offset_x_mm;            /* centre of the rectangle, default 0 */
	double outline_offset_y_mm;            /* default 0 */
	uint8_t shock_count;                   /* 0..SIM_MAX_SHOCK, default 6 */
	struct sim_point shock[SIM_MAX_SHOCK]; /* default: front and rear, left/centre/right */
	double shock_range_mm; /* a switch closes within this distance of a border, default 1 */
	bool basket_sensor;    /* default true */
	struct sim_point basket_sensor_pos; /* default the middle of the front edge */
	uint8_t line_sensor_count;          /* 0..SIM_MAX_LINE_SENSORS, default 2 */
	struct sim_point line_sensor[SIM_MAX_LINE_SENSORS]; /* default (0, +/-40) under the axis */

	/* Contacts of the outline with borders and obstacles: penalty spring-damper */
	double wall_stiffness_N_m;  /* default 1e6 (0.04 mm under a 40 N push) */
	double wall_damping_N_s_m;  /* default 2000 */
	double wall_friction_coeff; /* sliding friction along a border, default 0.2 (GUESS) */

	/* Integration and start */
	uint32_t substep_ns;        /* 1000..1000000, default 100000 (100 us) */
	uint32_t coarse_substep_ns; /* the substep away from every contact, used for whole calls of
				     * sim_advance_ns() that are a multiple of it (a control tick);
				     * 0 (the default) or <= substep_ns: never; ignored if not
				     * stable; a multiple of substep_ns */
	struct sim_pose start;      /* pose of the drive axis midpoint, default (-1300, 0, 0) */
	uint64_t seed;              /* seeds the encoder noise */
};

/* Fills cfg with the defaults listed above. */
void sim_config_defaults(struct sim_config *cfg);

/* Perturbs cfg like one robot off the shelf, deterministically from seed: free wheel diameter
 * mismatch uniform in +/-0.3 %, track error uniform in +/-1 mm, noise k uniform in 0.04..0.25
 * mm^2/m per wheel, start pose error uniform in +/-2 mm and +/-0.5 deg (GUESS: hand placement
 * against a border), and cfg->seed derived from seed. */
void sim_config_randomize(struct sim_config *cfg, uint64_t seed);

/* ---------------------------------------------------------------------------------------------
 * Instance
 */

/* Readings, as the board's hardware would see them. */
struct sim_sensors {
	uint16_t enc_count[2];   /* free wheels, free-running (wraps) */
	int64_t enc_total[2];    /* the same, unwrapped: diff it to emit quadrature edges */
	uint16_t motor_count[2]; /* motor shaft encoders, free-running */
	int64_t motor_total[2];
	int32_t current_mA[2]; /* motor currents, signed like the duty */
	uint8_t shock_mask;    /* bit i: shock switch i closed */
	bool basket;           /* the basket switch is closed */
	uint8_t line_mask;     /* bit i: line sensor i is above a line */
};

/* Ground truth, for tests and plots (never for the firmware). */
struct sim_truth {
	struct sim_pose pose; /* midpoint of the drive axis */
	struct sim_pose
		odo_pose; /* midpoint of the true encoder wheel axis (the spec's reference) */
	double vx_mm_s;   /* field frame */
	double vy_mm_s;
	double v_mm_s;         /* forward speed, robot frame */
	double v_lateral_mm_s; /* sideways speed, robot frame (non-zero when skidding) */
	double omega_rad_s;
	double wheel_speed_mm_s[2]; /* drive wheel surface speeds */
	double slip_mm_s[2];        /* wheel surface speed minus ground speed, along the wheel */
	double current_A[2];
	double contact_force_N; /* sum of the border/obstacle normal forces on the outline */
	uint64_t time_ns;
};

/* An obstacle that moves along a path of points at a constant speed (an opponent robot seen as
 * a disc, or as its outline): it goes from its position to path[0], then to path[1], and so
 * on; at the end it stops, or starts again from path[0] if loop. It closes the shock switches
 * it comes within reach of, like any obstacle; it is not pushed by the robot. */
struct sim_opponent {
	uint8_t obstacle; /* index in the field's obstacles */
	uint8_t n_points; /* 0: stands still */
	uint8_t next;     /* the point it heads for */
	bool loop;
	double speed_mm_s;
	double path_mm[SIM_MAX_PATH][2];
};

/* One simulated robot on one field. Allocate it yourself; the members are private. */
struct sim {
	struct sim_config cfg;
	struct sim_field field;
	/* derived constants, SI (set by sim_init) */
	double dt_s, r_m, half_track_m, n_wheel_N, j_wheel, inv_j_wheel, inv_mass, inv_inertia;
	double kt, ke_wheel, inv_resistance, i_decay, gain_wheel, friction_wheel,
		inv_friction_w_eps;
	double c_eff, inv_tyre_k, a_long[2], a_lat; /* implicit tyre force: [free, stuck wheel] */
	double inv_den_long[2], inv_den_lat;
	double enc_y_m[2], enc_cnt_per_m[2], motor_cnt_per_wheel_step, enc_offset_x_m;
	double motor_cnt_per_rad, step_decay[2]; /* [short, long substep] */
	uint32_t coarse_ns;                      /* the long substep, 0: none */
	int coarse;                              /* the coefficients are those of the long one */
	double grip_use2;    /* the last call's largest tyre force^2 times the other's grip^2 */
	double coarse_grip2; /* grip_use2 must stay below this for the long substep */
	double corner_m[4][2], bound_radius_m, reach_m;
	/* coefficients of a substep, from the constants above and the fault settings */
	double cur_decay, cur_per_w, cur_in[2], px_per_tau[2], w_per_tau[2], f_per_tau[2];
	double f_per_tread_long[2], f_per_slip_long[2], f_per_tread_lat, f_per_slip_lat;
	double grip2_N2[2], v_per_f, omega_per_torque, omega_per_dfx, friction_per_w;
	double motor_cnt_per_w[2], enc_cnt_per_u[2], enc_cnt_per_omega[2], noise_var_cnt[2];
	double line_box[SIM_MAX_LINES][4]; /* each line's bounding box [mm] (field_line_boxes) */
	/* state, SI */
	double x, y, heading, cos_h, sin_h, vx, vy, omega;
	double wheel_w[2], current[2], slip[2], contact_force;
	double tread_m[2][2];            /* tyre deflection [m]: [wheel][along, across] */
	double enc_pos[2], motor_pos[2]; /* [counts], continuous */
	double noise_cnt[2];             /* |ds| not yet given its noise [counts] */
	double clearance_m;              /* the outline touches nothing before moving this far */
	uint8_t line_mask;               /* the line sensors (update_lines() in robot.c) ... */
	double line_ref_mm[SIM_MAX_LINE_SENSORS][2]; /* ... computed with them here, field frame */
	double line_margin_mm; /* ... and valid until one moves this far from there */
	int16_t duty_q15[2];
	double battery_V, volts_per_q15, volts[2], mu_scale[2], grip_N[2];
	bool motor_stuck[2], enc_cut[2], motor_enc_cut[2];
	struct sim_rng rng;
	uint64_t time_ns, carry_ns;
	uint64_t steps;      /* the time in substeps: a long one counts as the short ones it
			      * spans (step_units), so that the encoder noise is drawn at the
			      * same ticks, from the same random numbers, with either */
	uint64_t step_units; /* 1, or coarse_ns / substep_ns during long substeps */
	uint64_t short_steps, coarse_steps;        /* substeps run, of each length (for tests) */
	uint64_t fine_until_ns;                    /* short substeps until then (after a contact) */
	uint64_t split_ns, split_n, split_rest_ns; /* the last time sim_advance_ns() divided */
	uint8_t shock_forced;                      /* switches held closed by sim_force_sensors() */
	bool basket_forced;
	uint8_t opponent_count; /* (last: the hot state above stays in fewer cache lines) */
	struct sim_opponent opponents[SIM_MAX_OPPONENTS];
};

/* Sets up s from cfg and field (both copied) at cfg->start, at rest, duties 0, counters 0.
 * Returns 0, or -SIM_EINVAL if a value is out of range or the substep is too long for the
 * stiffness of the contacts (then s is unusable). */
int sim_init(struct sim *s, const struct sim_config *cfg, const struct sim_field *field);

/* Motor duty cycles [2^-15 of the battery voltage], -32767..32767 (-32768 is taken as -32767).
 * Held until the next call. */
void sim_set_duty(struct sim *s, int16_t left_q15, int16_t right_q15);

/* Advances one substep (cfg.substep_ns). */
void sim_step(struct sim *s);

/* Advances by duration_ns, in whole substeps; a remainder is carried to the next call so that
 * the simulated time follows the requested time (sim_advance_ns(s, 1000000) = one 1 kHz tick). */
void sim_advance_ns(struct sim *s, uint64_t duration_ns);

/* Reads the sensors at the current instant. */
void sim_read_sensors(const struct sim *s, struct sim_sensors *out);

/* Reads the ground truth at the current instant. */
void sim_get_truth(const struct sim *s, struct sim_truth *out);

/* Puts the robot (drive axis midpoint) at pose, at rest (the hand of the team). Counters keep
 * their values. */
void sim_set_pose(struct sim *s, const struct sim_pose *pose);

/* Fault injection and disturbances; wheel is SIM_LEFT or SIM_RIGHT, others are ignored. */
void sim_set_battery_V(struct sim *s, double volts);                 /* sag: e.g. 24 * 0.85 */
void sim_set_friction_scale(struct sim *s, int wheel, double scale); /* mu * scale, >= 0 */
void sim_set_motor_stuck(struct sim *s, int wheel, bool stuck);      /* shaft locked */
void sim_set_encoder_cut(struct sim *s, int wheel, bool cut);        /* free wheel stops counting */
void sim_set_motor_encoder_cut(struct sim *s, int wheel, bool cut);  /* motor encoder stops */

/* Switches held closed, whatever the geometry says (a hand, a stuck bumper): bit i of shock_mask
 * closes shock switch i; basket closes the basket switch. 0 and false release them. */
void sim_force_sensors(struct sim *s, uint8_t shock_mask, bool basket);

/* Moving obstacles. sim_add_obstacle() appends o to the field and returns its index, or
 * -SIM_EINVAL if the field is full or o is not a valid obstacle. sim_move_obstacle() puts
 * obstacle i at (x_mm, y_mm, heading_rad) at once (ignored for a bad i). The robot's contacts
 * are looked at again after either. */
int sim_add_obstacle(struct sim *s, const struct sim_obstacle *o);
void sim_move_obstacle(struct sim *s, int i, double x_mm, double y_mm, double heading_rad);

/* Makes obstacle i an opponent that follows path (n points, x y pairs in mm, n <= SIM_MAX_PATH)
 * at speed_mm_s (> 0), from where it is, starting now; a new path replaces the old one, n = 0
 * stops it. It moves at each sim_advance_ns() call (each control tick of a host) by the
 * distance of the call. Returns 0, or -SIM_EINVAL (bad index or path, no opponent left). */
int sim_set_opponent_path(struct sim *s, int i, const double *path_mm, int n, double speed_mm_s,
			  bool loop);

#endif /* ASSERV_SIM_H */
