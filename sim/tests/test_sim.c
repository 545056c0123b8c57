/* Tests of the physics simulator: motor, traction, encoders, contacts, sensors, determinism. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include <cmocka.h>

#include "sim.h"

#define PI 3.14159265358979323846
#define TICK_NS 1000000u
#define Q15(x) ((int16_t)((x)*32767.0))

/* Figures the tests check against, from the defaults (physics.md) */
#define KV_RAD_S_V (407.0 * 2.0 * PI / 60.0)
#define GEAR 20.25
#define R_DRIVE_M 0.0325
#define R_OHM 2.32
#define KT 0.0234
#define ETA 0.75
#define MU 0.8
#define SHARE 0.6
#define MASS 8.0
#define G 9.80665

#define assert_near(a, b, tol) assert_true(fabs((double)(a) - (double)(b)) <= (tol))

static void setup_sim(struct sim *s, struct sim_config *cfg, struct sim_field *field)
{
	assert_int_equal(sim_init(s, cfg, field), 0);
}

static void defaults(struct sim_config *cfg, struct sim_field *field, bool borders)
{
	sim_config_defaults(cfg);
	sim_field_defaults(field);
	field->borders = borders;
	if (!borders)
		field->obstacle_count = 0;
}

static void run_ms(struct sim *s, int ms)
{
	int i;

	for (i = 0; i < ms; i++)
		sim_advance_ns(s, TICK_NS);
}

static struct sim_truth truth(const struct sim *s)
{
	struct sim_truth t;

	sim_get_truth(s, &t);
	return t;
}

static struct sim_sensors sensors(const struct sim *s)
{
	struct sim_sensors o;

	sim_read_sensors(s, &o);
	return o;
}

/* On a stand, full duty: the wheel turns at Kv V / N (less the motor's own friction). */
static void test_lifted_no_load_speed(void **state)
{
	struct sim_config cfg;
	struct sim_field field;
	struct sim s;
	double expect = KV_RAD_S_V * 24.0 / GEAR * R_DRIVE_M * 1000.0; /* [mm/s] */
	struct sim_truth t;

	(void)state;
	defaults(&cfg, &field, true);
	cfg.lifted = true;
	setup_sim(&s, &cfg, &field);
	sim_set_duty(&s, 32767, -32767);
	run_ms(&s, 300);
	t = truth(&s);
	assert_near(t.wheel_speed_mm_s[0], expect, 0.01 * expect);
	assert_near(t.wheel_speed_mm_s[1], -expect, 0.01 * expect);
	assert_near(t.pose.x_mm, cfg.start.x_mm, 0.0);
	/* no-load current is the friction torque over Kt: ~30 mA */
	assert_near(t.current_A[0], 0.7e-3 / KT, 0.005);

	/* battery sag scales the no-load speed */
	sim_set_battery_V(&s, 24.0 * 0.85);
	run_ms(&s, 300);
	t = truth(&s);
	assert_near(t.wheel_speed_mm_s[0], 0.85 * expect, 0.01 * expect);
}

/* On the floor, half duty: the robot cruises at Kv V / N r. */
static void test_ground_cruise_speed(void **state)
{
	struct sim_config cfg;
	struct sim_field field;
	struct sim s;
	double expect = KV_RAD_S_V * 12.0 / GEAR * R_DRIVE_M * 1000.0;
	struct sim_truth t;

	(void)state;
	defaults(&cfg, &field, false);
	setup_sim(&s, &cfg, &field);
	sim_set_duty(&s, Q15(0.5), Q15(0.5));
	run_ms(&s, 1000);
	t = truth(&s);
	assert_near(t.v_mm_s, expect, 0.02 * expect);
	assert_near(t.slip_mm_s[0], 0.0, 0.5);
}

/* Equal duties, no mismatch: a straight line to the last bit of the heading. */
static void test_straight_line(void **state)
{
	struct sim_config cfg;
	struct sim_field field;
	struct sim s;
	struct sim_truth t;

	(void)state;
	defaults(&cfg, &field, false);
	setup_sim(&s, &cfg, &field);
	sim_set_duty(&s, Q15(0.3), Q15(0.3));
	run_ms(&s, 2000);
	t = truth(&s);
	assert_true(t.pose.x_mm - cfg.start.x_mm > 800.0);
	assert_near(t.pose.heading_rad, 0.0, 1e-12);
	assert_near(t.pose.y_mm, 0.0, 1e-9);
	assert_int_equal(sensors(&s).enc_total[0], sensors(&s).enc_total[1]);
}

/* Counts = distance / (2 pi r_true) * cpr on both free wheels and, without slip, on the motors. */
static void test_encoder_counts(void **state)
{
	static const uint32_t cprs[2] = {2000, 16384};
	int k;

	(void)state;
	for (k = 0; k < 2; k++) {
		struct sim_config cfg;
		struct sim_field field;
		struct sim s;
		struct sim_sensors o;
		double d_mm, expect;
		int i;

		defaults(&cfg, &field, false);
		cfg.enc_cpr = cprs[k];
		cfg.enc_radius_error[SIM_LEFT] = 0.003;
		cfg.enc_radius_error[SIM_RIGHT] = -0.002;
		setup_sim(&s, &cfg, &field);
		sim_set_duty(&s, Q15(0.2), Q15(0.2));
		run_ms(&s, 1500);
		sim_set_duty(&s, 0, 0);
		run_ms(&s, 500);
		d_mm = truth(&s).odo_pose.x_mm - cfg.start.x_mm;
		assert_true(d_mm > 300.0);
		o = sensors(&s);
		for (i = 0; i < 2; i++) {
			expect = d_mm / (2.0 * PI * 25.0 * (1.0 + cfg.enc_radius_error[i])) *
				 cprs[k];
			assert_near((double)o.enc_total[i], expect, 1.0);
			assert_int_equal(o.enc_count[i], (uint16_t)o.enc_total[i]);
			/* gentle start: the drive wheels roll within 0.5 % of the ground */
			expect = d_mm / (2.0 * PI * 32.5) * GEAR * 2048.0;
			assert_near((double)o.motor_total[i], expect, 0.005 * expect);
		}
	}
}

/* Gentle push into a border: the wall stops the robot, the wheels stall (the stall force at 5 %
 * duty is below the grip), the current rises to the stall current u / R. */
static void test_wall_stall(void **state)
{
	struct sim_config cfg;
	struct sim_field field;
	struct sim s;
	struct sim_sensors a, b;
	struct sim_truth t;
	double duty = 0.05, i_stall = duty * 24.0 / R_OHM;
	int i;

	(void)state;
	defaults(&cfg, &field, true);
	cfg.start.x_mm = 1300.0; /* front edge 75 mm from the border at x = 1500 */
	setup_sim(&s, &cfg, &field);
	sim_set_duty(&s, Q15(duty), Q15(duty));
	run_ms(&s, 2500);
	a = sensors(&s);
	run_ms(&s, 500);
	b = sensors(&s);
	t = truth(&s);
	assert_near(t.pose.x_mm, 1500.0 - 125.0, 0.5);
	assert_near(t.v_mm_s, 0.0, 0.1);
	assert_near(t.pose.heading_rad, 0.0, 1e-6);
	for (i = 0; i < 2; i++) {
		assert_near(t.current_A[i], i_stall, 0.02 * i_stall);
		assert_near(b.current_mA[i], 1000.0 * i_stall, 0.02 * 1000.0 * i_stall);
		assert_true(b.motor_total[i] - a.motor_total[i] <= 1);
		assert_true(b.enc_total[i] - a.enc_total[i] <= 1);
	}
}

/* Full push into a border: the robot is traction-limited, so the wheels slip instead of
 * stalling: the free wheels stop, the motor encoders keep counting, the current sits at the
 * current that makes mu N of wheel force, far below the 10 A stall current. */
static void test_wall_full_duty_slips(void **state)
{
	struct sim_config cfg;
	struct sim_field field;
	struct sim s;
	struct sim_sensors a, b;
	struct sim_truth t;
	double n_wheel = MASS * G * SHARE / 2.0;
	double i_grip = MU * n_wheel * R_DRIVE_M / (ETA * GEAR * KT) + 0.7e-3 / KT;
	int i;

	(void)state;
	defaults(&cfg, &field, true);
	cfg.start.x_mm = 1370.0;
	setup_sim(&s, &cfg, &field);
	sim_set_duty(&s, 32767, 32767);
	run_ms(&s, 800);
	a = sensors(&s);
	run_ms(&s, 200);
	b = sensors(&s);
	t = truth(&s);
	assert_near(t.pose.x_mm, 1375.0, 0.5);
	assert_near(t.contact_force_N, 2.0 * MU * n_wheel, 0.03 * 2.0 * MU * n_wheel);
	for (i = 0; i < 2; i++) {
		assert_near(t.current_A[i], i_grip, 0.03 * i_grip);
		assert_true(b.enc_total[i] - a.enc_total[i] <= 1);
		assert_true(b.motor_total[i] - a.motor_total[i] > 10000); /* still spinning */
		assert_true(t.slip_mm_s[i] > 1000.0);
	}
}

/* Asking for more than mu g f_d: the robot accelerates at mu g f_d and the motor encoders run
 * ahead of the free wheels. */
static void test_hard_acceleration_slips(void **state)
{
	struct sim_config cfg;
	struct sim_field field;
	struct sim s;
	struct sim_sensors o;
	double v1, v2, a_lim = MU * G * SHARE, d_free, d_motor;

	(void)state;
	defaults(&cfg, &field, false);
	setup_sim(&s, &cfg, &field);
	sim_set_duty(&s, 32767, 32767);
	run_ms(&s, 50);
	v1 = truth(&s).v_mm_s;
	run_ms(&s, 100);
	v2 = truth(&s).v_mm_s;
	/* (v2 - v1) / 0.1 s [mm/s^2] */
	assert_near((v2 - v1) * 10.0 * 1e-3, a_lim, 0.03 * a_lim);
	o = sensors(&s);
	d_free = o.enc_total[0] * (2.0 * PI * 25.0) / 2000.0;
	d_motor = o.motor_total[0] / 2048.0 / GEAR * (2.0 * PI * 32.5);
	assert_true(d_motor > 1.5 * d_free);
	assert_true(truth(&s).slip_mm_s[0] > 100.0);
}

/* Same seed, same calls: the same bits. Another seed: other noise. */
static void run_pattern(struct sim *s, struct sim_sensors *trace, int ms)
{
	int i;

	for (i = 0; i < ms; i++) {
		int16_t l = (int16_t)((i / 300) % 2 ? 20000 : -8000);
		int16_t r = (int16_t)((i / 700) % 2 ? 30000 : 12000);

		sim_set_duty(s, l, r);
		sim_advance_ns(s, TICK_NS);
		sim_read_sensors(s, &trace[i]);
	}
}

static void test_determinism(void **state)
{
	enum { MS = 3000 };
	static struct sim_sensors ta[MS], tb[MS];
	struct sim_config cfg;
	struct sim_field field;
	struct sim a, b;
	struct sim_truth xa, xb;

	(void)state;
	defaults(&cfg, &field, true);
	cfg.start.x_mm = 0.0;
	cfg.start.y_mm = 300.0;
	sim_config_randomize(&cfg, 1234);
	setup_sim(&a, &cfg, &field);
	setup_sim(&b, &cfg, &field);
	memset(ta, 0, sizeof(ta));
	memset(tb, 0, sizeof(tb));
	run_pattern(&a, ta, MS);
	run_pattern(&b, tb, MS);
	assert_memory_equal(ta, tb, sizeof(ta));
	sim_get_truth(&a, &xa);
	sim_get_truth(&b, &xb);
	assert_memory_equal(&xa, &xb, sizeof(xa));

	cfg.seed ^= 1; /* only the noise differs */
	setup_sim(&b, &cfg, &field);
	run_pattern(&b, tb, MS);
	sim_get_truth(&b, &xb);
	assert_memory_equal(&xa.pose, &xb.pose, sizeof(xa.pose));
	assert_true(ta[MS - 1].enc_total[0] != tb[MS - 1].enc_total[0] ||
		    ta[MS - 1].enc_total[1] != tb[MS - 1].enc_total[1]);
}

/* The spread of the free wheel noise over 1 m matches sqrt(k * 1 m). */
static void test_encoder_noise_spread(void **state)
{
	enum { RUNS = 64 };
	double k = 0.25, sum = 0.0, sum2 = 0.0, mean, sd, cnt_per_mm = 16384.0 / (2.0 * PI * 25.0);
	int run;

	(void)state;
	for (run = 0; run < RUNS; run++) {
		struct sim_config cfg;
		struct sim_field field;
		struct sim s;
		double d_mm, err;

		defaults(&cfg, &field, false);
		cfg.enc_cpr = 16384;
		cfg.enc_noise_mm2_per_m[0] = k;
		cfg.seed = 1000 + (uint64_t)run;
		setup_sim(&s, &cfg, &field);
		sim_set_duty(&s, Q15(0.5), Q15(0.5));
		run_ms(&s, 1300);
		sim_set_duty(&s, 0, 0);
		run_ms(&s, 300);
		d_mm = truth(&s).odo_pose.x_mm - cfg.start.x_mm;
		err = sensors(&s).enc_total[0] / cnt_per_mm - d_mm;
		sum += err;
		sum2 += err * err;
		if (run == 0)
			assert_true(d_mm > 900.0 && d_mm < 1300.0);
	}
	mean = sum / RUNS;
	sd = sqrt(sum2 / RUNS - mean * mean);
	/* about 1 m: sd ~ 0.5 mm; 64 runs estimate it within ~20 % */
	assert_true(sd > 0.35 && sd < 0.7);
	assert_near(mean, 0.0, 0.25);
}

/* Crossing the line x = 0 (20 mm wide): the sensors under the axis see it over +/-10 mm. */
static void test_line_sensor(void **state)
{
	struct sim_config cfg;
	struct sim_field field;
	struct sim s;
	double first_on = 1e9, last_on = -1e9;
	int i;

	(void)state;
	defaults(&cfg, &field, true);
	cfg.start.x_mm = -200.0;
	cfg.start.y_mm = 300.0; /* away from the line y = 0 */
	setup_sim(&s, &cfg, &field);
	assert_int_equal(sensors(&s).line_mask, 0);
	sim_set_duty(&s, Q15(0.1), Q15(0.1));
	for (i = 0; i < 4000; i++) {
		double x;

		sim_advance_ns(&s, TICK_NS);
		x = truth(&s).pose.x_mm;
		if (sensors(&s).line_mask == 3) {
			if (first_on > 1e8)
				first_on = x;
			last_on = x;
		} else {
			assert_int_equal(sensors(&s).line_mask, 0);
		}
		if (x > 200.0)
			break;
	}
	/* 0.16 m/s: 0.16 mm per tick */
	assert_near(first_on, -10.0, 0.3);
	assert_near(last_on, 10.0, 0.3);
}

/* Driving into a border closes the front shock switches only, and not the basket switch. */
static void test_shock_sensor_at_wall(void **state)
{
	struct sim_config cfg;
	struct sim_field field;
	struct sim s;
	struct sim_sensors o;

	(void)state;
	defaults(&cfg, &field, true);
	cfg.start.x_mm = 1300.0;
	cfg.start.y_mm = 300.0;
	setup_sim(&s, &cfg, &field);
	assert_int_equal(sensors(&s).shock_mask, 0);
	sim_set_duty(&s, Q15(0.1), Q15(0.1));
	run_ms(&s, 300);
	assert_int_equal(sensors(&s).shock_mask, 0);
	run_ms(&s, 1500);
	o = sensors(&s);
	assert_int_equal(o.shock_mask, 0x07);
	assert_false(o.basket);
	assert_true(truth(&s).contact_force_N > 1.0);

	/* backing away opens them again */
	sim_set_duty(&s, Q15(-0.1), Q15(-0.1));
	run_ms(&s, 300);
	assert_int_equal(sensors(&s).shock_mask, 0);
	assert_near(truth(&s).contact_force_N, 0.0, 0.0);
}

/* Driving into a basket (circle r 125 at (1200, -750)) closes the basket switch and stops. */
static void test_basket_sensor(void **state)
{
	struct sim_config cfg;
	struct sim_field field;
	struct sim s;
	struct sim_sensors o;
	struct sim_truth t;

	(void)state;
	defaults(&cfg, &field, true);
	cfg.start.x_mm = 850.0;
	cfg.start.y_mm = -750.0;
	setup_sim(&s, &cfg, &field);
	assert_false(sensors(&s).basket);
	sim_set_duty(&s, Q15(0.1), Q15(0.1));
	run_ms(&s, 2500);
	o = sensors(&s);
	t = truth(&s);
	assert_true(o.basket);
	assert_true(o.shock_mask & 0x02); /* front centre */
	/* front edge (x + 125) on the basket's surface (1200 - 125) */
	assert_near(t.pose.x_mm, 1200.0 - 125.0 - 125.0, 0.5);
	assert_near(t.v_mm_s, 0.0, 0.1);
}

/* A box obstacle stops the robot too. */
static void test_box_obstacle(void **state)
{
	struct sim_config cfg;
	struct sim_field field;
	struct sim s;
	struct sim_obstacle *o;

	(void)state;
	defaults(&cfg, &field, true);
	o = &field.obstacles[field.obstacle_count++];
	o->shape = SIM_SHAPE_BOX;
	o->kind = SIM_OBSTACLE_OTHER;
	o->x_mm = 0.0;
	o->y_mm = 600.0;
	o->half_x_mm = 50.0;
	o->half_y_mm = 100.0;
	cfg.start.x_mm = -300.0;
	cfg.start.y_mm = 600.0;
	setup_sim(&s, &cfg, &field);
	sim_set_duty(&s, Q15(0.1), Q15(0.1));
	run_ms(&s, 2500);
	assert_near(truth(&s).pose.x_mm, -50.0 - 125.0, 0.5);
	/* the box is 200 mm wide: the front centre switch touches it, the side ones (+/-140) not */
	assert_int_equal(sensors(&s).shock_mask, 0x02);
	assert_false(sensors(&s).basket);
}

static void test_faults(void **state)
{
	struct sim_config cfg;
	struct sim_field field;
	struct sim s;
	struct sim_sensors a, b;
	struct sim_truth t;

	(void)state;
	defaults(&cfg, &field, false);
	setup_sim(&s, &cfg, &field);
	sim_set_duty(&s, Q15(0.3), Q15(0.3));
	run_ms(&s, 500);

	/* a cut wire: the left free wheel counter stops, the right one goes on */
	sim_set_encoder_cut(&s, SIM_LEFT, true);
	a = sensors(&s);
	run_ms(&s, 200);
	b = sensors(&s);
	assert_int_equal(b.enc_total[0], a.enc_total[0]);
	assert_true(b.enc_total[1] - a.enc_total[1] > 100);
	sim_set_encoder_cut(&s, SIM_LEFT, false);

	/* a stuck motor: its encoder stops, its current goes to u / R, the robot turns towards it
	 */
	sim_set_motor_stuck(&s, SIM_LEFT, true);
	a = sensors(&s);
	run_ms(&s, 300);
	b = sensors(&s);
	t = truth(&s);
	assert_int_equal(b.motor_total[0], a.motor_total[0]);
	assert_near(t.current_A[0], 0.3 * 24.0 / R_OHM, 0.01);
	assert_true(t.omega_rad_s > 0.5); /* pivots on the locked left wheel: turns left */
	sim_set_motor_stuck(&s, SIM_LEFT, false);

	/* no grip under the right wheel: it spins, the robot pivots on the left wheel */
	sim_set_pose(&s, &cfg.start);
	sim_set_friction_scale(&s, SIM_RIGHT, 0.0);
	run_ms(&s, 300);
	t = truth(&s);
	assert_true(t.slip_mm_s[1] > 300.0);
	assert_true(t.omega_rad_s < -0.5);
}

static void test_advance_carries_remainder(void **state)
{
	struct sim_config cfg;
	struct sim_field field;
	struct sim s;

	(void)state;
	defaults(&cfg, &field, true);
	setup_sim(&s, &cfg, &field);
	sim_advance_ns(&s, 150000);
	assert_int_equal(truth(&s).time_ns, 100000);
	sim_advance_ns(&s, 150000);
	assert_int_equal(truth(&s).time_ns, 300000);
	sim_advance_ns(&s, TICK_NS);
	assert_int_equal(truth(&s).time_ns, 1300000);
}

static void test_randomize_and_checks(void **state)
{
	struct sim_config a, b;
	struct sim_field field;
	struct sim s;
	uint64_t seed;

	(void)state;
	sim_field_defaults(&field);
	for (seed = 0; seed < 200; seed++) {
		sim_config_defaults(&a);
		sim_config_randomize(&a, seed);
		sim_config_defaults(&b);
		sim_config_randomize(&b, seed);
		assert_memory_equal(&a, &b, sizeof(a));
		assert_true(fabs(a.enc_radius_error[0]) <= 0.003);
		assert_true(fabs(a.enc_radius_error[1]) <= 0.003);
		assert_true(fabs(a.enc_track_error_mm) <= 1.0);
		assert_true(a.enc_noise_mm2_per_m[0] >= 0.04 && a.enc_noise_mm2_per_m[0] <= 0.25);
		assert_true(fabs(a.start.x_mm + 1300.0) <= 2.0);
		assert_true(fabs(a.start.heading_rad) <= 0.5 * PI / 180.0);
		assert_int_equal(sim_init(&s, &a, &field), 0);
	}
	/* invalid or unstable settings are refused */
	sim_config_defaults(&a);
	a.mass_kg = 0.0;
	assert_int_equal(sim_init(&s, &a, &field), -SIM_EINVAL);
	sim_config_defaults(&a);
	a.substep_ns = 1000000;
	a.wall_stiffness_N_m = 1e8;
	assert_int_equal(sim_init(&s, &a, &field), -SIM_EINVAL);
}

static void test_rng_gauss_moments(void **state)
{
	struct sim_rng r;
	double sum = 0.0, sum2 = 0.0;
	int i, n = 200000;

	(void)state;
	sim_rng_seed(&r, 99);
	for (i = 0; i < n; i++) {
		double g = sim_rng_gauss(&r);

		sum += g;
		sum2 += g * g;
	}
	assert_near(sum / n, 0.0, 0.01);
	assert_near(sum2 / n, 1.0, 0.01);
}

int main(void)
{
	const struct CMUnitTest tests[] = {
		cmocka_unit_test(test_lifted_no_load_speed),
		cmocka_unit_test(test_ground_cruise_speed),
		cmocka_unit_test(test_straight_line),
		cmocka_unit_test(test_encoder_counts),
		cmocka_unit_test(test_wall_stall),
		cmocka_unit_test(test_wall_full_duty_slips),
		cmocka_unit_test(test_hard_acceleration_slips),
		cmocka_unit_test(test_determinism),
		cmocka_unit_test(test_encoder_noise_spread),
		cmocka_unit_test(test_line_sensor),
		cmocka_unit_test(test_shock_sensor_at_wall),
		cmocka_unit_test(test_basket_sensor),
		cmocka_unit_test(test_box_obstacle),
		cmocka_unit_test(test_faults),
		cmocka_unit_test(test_advance_carries_remainder),
		cmocka_unit_test(test_randomize_and_checks),
		cmocka_unit_test(test_rng_gauss_moments),
	};

	return cmocka_run_group_tests(tests, NULL, NULL);
}
