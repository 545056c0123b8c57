/* Default settings of the simulated robot, and their random perturbation for benchmarks. */
#include <string.h>

#include "robot_default_gen.h"
#include "sim.h"

void sim_config_defaults(struct sim_config *cfg)
{
	static const double shock_y[3] = {140.0, 0.0, -140.0};
	int i;

	memset(cfg, 0, sizeof(*cfg));
	/* the wheels, encoders, motor, body and outline of robot/default.toml */
	sim_robot_default_gen(cfg);
	cfg->tyre_stiffness_N_m = 1e5;
	cfg->slip_damping_N_s_m = 3000.0;
	cfg->lifted = false;

	cfg->shock_count = 6;
	for (i = 0; i < 3; i++) {
		cfg->shock[i].x_mm = 125.0;
		cfg->shock[i].y_mm = shock_y[i];
		cfg->shock[i + 3].x_mm = -125.0;
		cfg->shock[i + 3].y_mm = shock_y[i];
	}
	cfg->shock_range_mm = 1.0;
	cfg->basket_sensor = true;
	cfg->basket_sensor_pos.x_mm = 125.0;
	cfg->basket_sensor_pos.y_mm = 0.0;
	cfg->line_sensor_count = 2;
	cfg->line_sensor[0].y_mm = 40.0;
	cfg->line_sensor[1].y_mm = -40.0;

	cfg->wall_stiffness_N_m = 1e6;
	cfg->wall_damping_N_s_m = 2000.0;
	cfg->wall_friction_coeff = 0.2;

	cfg->substep_ns = 100000;
	/* Off by default: the 1 ms substep away from contacts is for speed runs
	 * (bench/sim_speed.py); it changed how an oblique shock ends (rest 136 -> 256 ms in
	 * test_endings_sim). */
	cfg->coarse_substep_ns = 0;
	cfg->start.x_mm = -1300.0;
	cfg->seed = 1;
}

void sim_config_randomize(struct sim_config *cfg, uint64_t seed)
{
	struct sim_rng r;
	int i;

	sim_rng_seed(&r, seed);
	for (i = 0; i < 2; i++)
		cfg->enc_radius_error[i] = sim_rng_range(&r, -0.003, 0.003);
	cfg->enc_track_error_mm = sim_rng_range(&r, -1.0, 1.0);
	for (i = 0; i < 2; i++)
		cfg->enc_noise_mm2_per_m[i] = sim_rng_range(&r, 0.04, 0.25);
	cfg->start.x_mm += sim_rng_range(&r, -2.0, 2.0);
	cfg->start.y_mm += sim_rng_range(&r, -2.0, 2.0);
	cfg->start.heading_rad += sim_rng_range(&r, -0.5, 0.5) * (3.14159265358979323846 / 180.0);
	cfg->seed = sim_rng_next(&r);
}
