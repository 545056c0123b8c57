/* Default settings of the simulated robot, and their random perturbation for benchmarks. */
#include <string.h>

#include "sim.h"

void sim_config_defaults(struct sim_config *cfg)
{
	static const double shock_y[3] = {140.0, 0.0, -140.0};
	int i;

	memset(cfg, 0, sizeof(*cfg));
	cfg->mass_kg = 8.0;
	/* a uniform 8 kg box of 250 x 300 mm: m (a^2 + b^2) / 12 = 0.102 kg m^2 */
	cfg->yaw_inertia_kg_m2 = 0.10;
	cfg->drive_weight_share = 0.6;
	cfg->friction_coeff = 0.8;
	cfg->tyre_stiffness_N_m = 1e5;
	cfg->slip_damping_N_s_m = 3000.0;
	cfg->drive_radius_mm = 32.5;
	cfg->drive_track_mm = 160.0;
	cfg->wheel_inertia_g_cm2 = 200.0;

	/* Maxon RE25 24 V graphite brushes with a 20.25:1 gearbox (APBTeam motor model) */
	cfg->motor.kv_rpm_per_V = 407.0;
	cfg->motor.kt_mNm_per_A = 23.4;
	cfg->motor.resistance_ohm = 2.32;
	cfg->motor.inductance_mH = 0.24;
	cfg->motor.rotor_inertia_g_cm2 = 10.3;
	cfg->motor.friction_mNm = 0.7; /* GUESS: ~30 mA of no-load current times Kt */
	cfg->motor.gear_ratio = 20.25;
	cfg->motor.gear_efficiency = 0.75;
	cfg->motor.encoder_cpr = 2048; /* 512 lines, x4 */
	cfg->battery_V = 24.0;
	cfg->lifted = false;

	cfg->enc_radius_mm = 25.0;
	cfg->enc_track_mm = 280.0;
	cfg->enc_offset_x_mm = 0.0;
	cfg->enc_cpr = 2000;

	cfg->outline_length_mm = 250.0;
	cfg->outline_width_mm = 300.0;
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
	cfg->coarse_substep_ns = 1000000;
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
