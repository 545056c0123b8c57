/* Dynamics of the simulated robot: motors, wheels on the table, body, encoders and sensors.
 *
 * Numerical method, one substep of dt (100 us by default):
 *   1. Motor current, exact for a frozen speed: di/dt = (u - R i - Ke w) / L, so
 *      i <- i_ss + (i - i_ss) exp(-dt R / L) with i_ss = (u - Ke w) / R. Stable at any dt; with
 *      L = 0 the current is i_ss (the 0.1 ms L/R constant is below the 1 ms control period).
 *   2. Tyre force of each drive wheel, an elasto-plastic (bristle) model: the tread deflects by z
 *      (the integral of the slip velocity s = wheel surface speed minus ground speed at the
 *      contact, a 2-D vector), F = k z + c s, and |F| is capped at mu N (friction circle: a wheel
 *      that spends its grip turning has less left for accelerating); when capped, the tread
 *      slides and z stays at F / k. The spring gives true static grip (a stalled wheel does not
 *      creep); the damper makes sliding smooth. The force is stiff (the wheel's own inertia,
 *      reflected through the gearbox, is light), so it is taken linearly implicit along each
 *      wheel: with c' = c + k dt and a = r^2/J + 1/m + y^2/I,
 *      F = (k z + c' (s + dt r tau / J)) / (1 + c' dt a), and likewise across the wheels for the
 *      lateral slip they share (a = 2/m). The coupling of the two wheels through the body's yaw
 *      is left explicit (it is 20 times weaker).
 *   3. Wheel speeds: J dw/dt = eta N Kt i - friction - r F_x (semi-implicit Euler).
 *   4. Contacts of the outline with borders and obstacles: a penalty spring-damper per contact
 *      point (k = 1e6 N/m, c = 2000 N s/m by default: 0.04 mm under a 40 N push), plus a
 *      regularised Coulomb friction along the wall. The wall stops the normal motion; the wheels
 *      then stall or slip, and the motor current shows it.
 *   5. Body: semi-implicit Euler in the field frame (velocities first, then positions with the
 *      new velocities). The heading's cosine and sine are rotated incrementally (a 4th-order
 *      exact rotation) and recomputed from the heading every 1024 substeps, so there is no libm
 *      call in the common path.
 *   6. Encoders: each free wheel rolls the ground distance of its contact point along the robot
 *      axis, plus noise of variance k |ds| (Chong & Kleeman 1997), converted with its true radius;
 *      motor encoders integrate the shaft angle. Counts are the floor of the continuous position.
 *
 * Stability limits are checked by sim_init(); with the defaults the largest explicit eigenvalue
 * times dt is about 0.15.
 *
 * Not modelled: load transfer between the wheels, gearbox backlash, battery internal resistance,
 * current limit of the H-bridge, caster drag, free wheel slip, bumps and seams.
 */
#include <math.h>
#include <string.h>

#include "field.h"
#include "sim.h"

#define G_M_S2 9.80665
#define PI 3.14159265358979323846
#define RESYNC_MASK 1023u
#define NOISE_MASK 15u
/* Coulomb friction of the motor is regularised below this motor speed [rad/s] */
#define MOTOR_FRICTION_W_EPS 2.0

/* Draws the accumulated encoder noise (see sim_step). */
static void add_noise(struct sim *s)
{
	int i;

	for (i = 0; i < 2; i++) {
		double k = s->cfg.enc_noise_mm2_per_m[i]; /* [mm^2/m] */

		if (k > 0.0 && s->noise_ds[i] > 0.0 && !s->enc_cut[i]) {
			double sigma_mm = sqrt(k * s->noise_ds[i]);

			s->enc_pos[i] +=
				1e-3 * sigma_mm * sim_rng_gauss(&s->rng) * s->enc_cnt_per_m[i];
		}
		s->noise_ds[i] = 0.0;
	}
}

/* Refreshes the clearance: distance from the drive axis midpoint to the nearest border or
 * obstacle, less the reach of the outline and switches (<= 0: contacts must be computed). */
static void update_clearance(struct sim *s)
{
	s->clearance_m = 1e-3 * field_distance(&s->field, 1000.0 * s->x, 1000.0 * s->y, FIELD_ALL) -
			 s->reach_m;
	if (s->clearance_m > 0.0)
		s->contact_force = 0.0;
}

static double clampd(double v, double lo, double hi)
{
	return v < lo ? lo : (v > hi ? hi : v);
}

static double wrap_pi(double a)
{
	while (a > PI)
		a -= 2.0 * PI;
	while (a <= -PI)
		a += 2.0 * PI;
	return a;
}

static bool positive(double v)
{
	return v > 0.0 && v < 1e12; /* also rejects NaN */
}

static int check_config(const struct sim_config *c, const struct sim_field *f)
{
	const struct sim_motor_config *m = &c->motor;

	if (!positive(c->mass_kg) || !positive(c->yaw_inertia_kg_m2) ||
	    !positive(c->drive_radius_mm) || !positive(c->drive_track_mm) ||
	    !positive(c->enc_radius_mm) || !positive(c->enc_track_mm) ||
	    !positive(c->slip_damping_N_s_m) || !positive(c->tyre_stiffness_N_m) ||
	    !positive(c->outline_length_mm) || !positive(c->outline_width_mm) ||
	    !positive(c->wall_stiffness_N_m))
		return -SIM_EINVAL;
	if (!(c->drive_weight_share > 0.0 && c->drive_weight_share <= 1.0) ||
	    !(c->friction_coeff >= 0.0) || !(c->wheel_inertia_g_cm2 >= 0.0) ||
	    !(c->wall_damping_N_s_m >= 0.0) || !(c->wall_friction_coeff >= 0.0) ||
	    !(c->shock_range_mm >= 0.0))
		return -SIM_EINVAL;
	if (!positive(m->kv_rpm_per_V) || !positive(m->kt_mNm_per_A) ||
	    !positive(m->resistance_ohm) || !positive(m->rotor_inertia_g_cm2) ||
	    !positive(m->gear_ratio) || !(m->gear_efficiency > 0.0 && m->gear_efficiency <= 1.0) ||
	    !(m->inductance_mH >= 0.0) || !(m->friction_mNm >= 0.0) || m->encoder_cpr == 0)
		return -SIM_EINVAL;
	if (c->enc_cpr == 0 || c->substep_ns < 1000 || c->substep_ns > 1000000 ||
	    c->shock_count > SIM_MAX_SHOCK || c->line_sensor_count > SIM_MAX_LINE_SENSORS)
		return -SIM_EINVAL;
	if (fabs(c->enc_radius_error[0]) >= 0.5 || fabs(c->enc_radius_error[1]) >= 0.5 ||
	    !(c->enc_noise_mm2_per_m[0] >= 0.0) || !(c->enc_noise_mm2_per_m[1] >= 0.0) ||
	    !(fabs(c->enc_track_error_mm) < 0.5 * c->enc_track_mm))
		return -SIM_EINVAL;
	if (!positive(f->length_mm) || !positive(f->width_mm) ||
	    f->obstacle_count > SIM_MAX_OBSTACLES || f->line_count > SIM_MAX_LINES)
		return -SIM_EINVAL;
	return 0;
}

/* The explicit parts must stay well inside their stability region (eigenvalue * dt < 0.5 for
 * the oscillators, < 1 for the dampers), with up to four contacts at once. */
static int check_stability(const struct sim *s)
{
	double dt = s->dt_s, m_eff, k = s->cfg.wall_stiffness_N_m, r2 = 0.0;
	double cross = s->inv_mass - s->half_track_m * s->half_track_m * s->inv_inertia;
	int i;

	for (i = 0; i < 4; i++)
		r2 = fmax(r2, s->corner_m[i][0] * s->corner_m[i][0] +
				      s->corner_m[i][1] * s->corner_m[i][1]);
	m_eff = 1.0 / (s->inv_mass + r2 * s->inv_inertia);
	if (dt * sqrt(4.0 * k / m_eff) > 0.5)
		return -SIM_EINVAL;
	if (4.0 * s->cfg.wall_damping_N_s_m * dt / m_eff > 1.0)
		return -SIM_EINVAL;
	if (s->friction_wheel * s->inv_friction_w_eps * dt * s->inv_j_wheel > 1.0)
		return -SIM_EINVAL;
	if (s->c_eff * dt * fabs(cross) > 0.5)
		return -SIM_EINVAL;
	return 0;
}

int sim_init(struct sim *s, const struct sim_config *cfg, const struct sim_field *field)
{
	const struct sim_motor_config *m = &cfg->motor;
	double n = m->gear_ratio, hl, hw, ox, oy;
	int i, err;

	memset(s, 0, sizeof(*s));
	err = check_config(cfg, field);
	if (err)
		return err;
	s->cfg = *cfg;
	s->field = *field;

	s->dt_s = cfg->substep_ns * 1e-9;
	s->r_m = cfg->drive_radius_mm * 1e-3;
	s->half_track_m = 0.5e-3 * cfg->drive_track_mm;
	s->n_wheel_N = cfg->mass_kg * G_M_S2 * cfg->drive_weight_share * 0.5;
	/* g cm^2 = 1e-7 kg m^2; the rotor is seen through the gearbox squared */
	s->j_wheel = 1e-7 * (m->rotor_inertia_g_cm2 * n * n + cfg->wheel_inertia_g_cm2);
	s->inv_j_wheel = 1.0 / s->j_wheel;
	s->inv_mass = 1.0 / cfg->mass_kg;
	s->inv_inertia = 1.0 / cfg->yaw_inertia_kg_m2;
	s->kt = m->kt_mNm_per_A * 1e-3;
	/* back-EMF per wheel speed [V s/rad]: Ke = 1 / Kv in SI, seen through the gearbox */
	s->ke_wheel = n * 60.0 / (2.0 * PI * m->kv_rpm_per_V);
	s->inv_resistance = 1.0 / m->resistance_ohm;
	s->i_decay = m->inductance_mH > 0.0
			     ? exp(-s->dt_s * m->resistance_ohm / (m->inductance_mH * 1e-3))
			     : 0.0;
	s->gain_wheel = m->gear_efficiency * n * s->kt;
	/* the friction is on the motor shaft, before the gearbox losses */
	s->friction_wheel = m->gear_efficiency * n * m->friction_mNm * 1e-3;
	s->inv_friction_w_eps = n / MOTOR_FRICTION_W_EPS;
	s->inv_tyre_k = 1.0 / cfg->tyre_stiffness_N_m;
	s->c_eff = cfg->slip_damping_N_s_m + cfg->tyre_stiffness_N_m * s->dt_s;
	for (i = 0; i < 2; i++) {
		double inv_j = i ? 0.0 : s->inv_j_wheel; /* a stuck wheel has no inertia to give */

		s->a_long[i] = s->r_m * s->r_m * inv_j + s->inv_mass +
			       s->half_track_m * s->half_track_m * s->inv_inertia;
		s->inv_den_long[i] = 1.0 / (1.0 + s->c_eff * s->dt_s * s->a_long[i]);
	}
	/* both wheels see the same lateral slip (they are on the y axis) and push the same mass */
	s->a_lat = 2.0 * s->inv_mass;
	s->inv_den_lat = 1.0 / (1.0 + s->c_eff * s->dt_s * s->a_lat);

	for (i = 0; i < 2; i++) {
		double true_r = cfg->enc_radius_mm * (1.0 + cfg->enc_radius_error[i]);
		double side = i == SIM_LEFT ? 1.0 : -1.0;

		s->enc_y_m[i] = side * 0.5e-3 * (cfg->enc_track_mm + cfg->enc_track_error_mm);
		s->enc_cnt_per_m[i] = 1000.0 * cfg->enc_cpr / (2.0 * PI * true_r);
		sim_set_friction_scale(s, i, 1.0);
	}
	s->motor_cnt_per_wheel_step = s->dt_s * n * m->encoder_cpr / (2.0 * PI);
	s->enc_offset_x_m = cfg->enc_offset_x_mm * 1e-3;

	hl = 0.5 * cfg->outline_length_mm;
	hw = 0.5 * cfg->outline_width_mm;
	ox = cfg->outline_offset_x_mm;
	oy = cfg->outline_offset_y_mm;
	for (i = 0; i < 4; i++) {
		s->corner_m[i][0] = 1e-3 * (ox + ((i & 1) ? hl : -hl));
		s->corner_m[i][1] = 1e-3 * (oy + ((i & 2) ? hw : -hw));
	}
	s->bound_radius_m = 1e-3 * sqrt(hl * hl + hw * hw);
	/* reach_m: radius around the drive axis midpoint holding the outline and every switch, so
	 * that nothing can touch while the clearance to the nearest border exceeds it */
	s->reach_m = 0.0;
	for (i = 0; i < 4; i++)
		s->reach_m = fmax(s->reach_m, hypot(s->corner_m[i][0], s->corner_m[i][1]));
	for (i = 0; i < cfg->shock_count; i++)
		s->reach_m = fmax(s->reach_m, 1e-3 * hypot(cfg->shock[i].x_mm, cfg->shock[i].y_mm));
	if (cfg->basket_sensor)
		s->reach_m = fmax(s->reach_m, 1e-3 * hypot(cfg->basket_sensor_pos.x_mm,
							   cfg->basket_sensor_pos.y_mm));
	s->reach_m += 1e-3 * cfg->shock_range_mm;

	err = check_stability(s);
	if (err)
		return err;

	sim_set_battery_V(s, cfg->battery_V);
	sim_rng_seed(&s->rng, cfg->seed);
	sim_set_pose(s, &cfg->start);
	return 0;
}

void sim_set_pose(struct sim *s, const struct sim_pose *pose)
{
	s->x = pose->x_mm * 1e-3;
	s->y = pose->y_mm * 1e-3;
	s->heading = wrap_pi(pose->heading_rad);
	s->cos_h = cos(s->heading);
	s->sin_h = sin(s->heading);
	s->vx = 0.0;
	s->vy = 0.0;
	s->omega = 0.0;
	s->wheel_w[0] = s->wheel_w[1] = 0.0;
	s->current[0] = s->current[1] = 0.0;
	s->slip[0] = s->slip[1] = 0.0;
	memset(s->tread_m, 0, sizeof(s->tread_m));
	s->contact_force = 0.0;
	s->clearance_m = 0.0; /* look again */
}

static void update_volts(struct sim *s)
{
	s->volts[SIM_LEFT] = s->duty_q15[SIM_LEFT] * s->volts_per_q15;
	s->volts[SIM_RIGHT] = s->duty_q15[SIM_RIGHT] * s->volts_per_q15;
}

void sim_set_duty(struct sim *s, int16_t left_q15, int16_t right_q15)
{
	s->duty_q15[SIM_LEFT] = left_q15 < -32767 ? -32767 : left_q15;
	s->duty_q15[SIM_RIGHT] = right_q15 < -32767 ? -32767 : right_q15;
	update_volts(s);
}

/* Adds the forces of the borders and obstacles on the outline to the field-frame force and the
 * torque about the drive axis midpoint. */
static void contact_forces(struct sim *s, double *fx, double *fy, double *torque)
{
	struct field_contact ct[FIELD_MAX_CONTACTS];
	struct field_rect r;
	const struct sim_config *cfg = &s->cfg;
	double c = s->cos_h, sn = s->sin_h, ox = cfg->outline_offset_x_mm;
	double oy = cfg->outline_offset_y_mm, total = 0.0;
	int i, n;

	r.cx = 1000.0 * s->x + ox * c - oy * sn;
	r.cy = 1000.0 * s->y + ox * sn + oy * c;
	r.ux = c;
	r.uy = sn;
	r.half_len = 0.5 * cfg->outline_length_mm;
	r.half_wid = 0.5 * cfg->outline_width_mm;
	r.bound = 1000.0 * s->bound_radius_m;
	n = field_collide(&s->field, &r, ct);
	for (i = 0; i < n; i++) {
		double rx = 1e-3 * ct[i].px - s->x, ry = 1e-3 * ct[i].py - s->y;
		double vpx = s->vx - s->omega * ry, vpy = s->vy + s->omega * rx;
		double nx = ct[i].nx, ny = ct[i].ny;
		double vn = vpx * nx + vpy * ny, vt = -vpx * ny + vpy * nx;
		double fn =
			cfg->wall_stiffness_N_m * 1e-3 * ct[i].depth - cfg->wall_damping_N_s_m * vn;
		double ft, lim, px, py;

		if (fn <= 0.0)
			continue; /* separating faster than the spring pushes: no pull */
		lim = cfg->wall_friction_coeff * fn;
		ft = clampd(-cfg->wall_damping_N_s_m * vt, -lim, lim);
		px = fn * nx - ft * ny;
		py = fn * ny + ft * nx;
		*fx += px;
		*fy += py;
		*torque += rx * py - ry * px;
		total += fn;
	}
	s->contact_force = total;
}

void sim_step(struct sim *s)
{
	const struct sim_config *cfg = &s->cfg;
	/* the state is copied to locals so that the compiler keeps it in registers */
	double dt = s->dt_s, r = s->r_m, ce = s->c_eff, k_tyre = cfg->tyre_stiffness_N_m;
	double c = s->cos_h, sn = s->sin_h, vx = s->vx, vy = s->vy, omega = s->omega;
	double u = vx * c + vy * sn;  /* forward speed */
	double v = -vx * sn + vy * c; /* lateral speed */
	double fxb = 0.0, fyb = 0.0, torque = 0.0, fx, fy, dth, dth2, cd, sd, w_new[2];
	bool sliding[2] = {false, false};
	int i;

	for (i = 0; i < 2; i++) {
		double yi = i == SIM_LEFT ? s->half_track_m : -s->half_track_m;
		double w = s->wheel_w[i];
		double i_ss = (s->volts[i] - s->ke_wheel * w) * s->inv_resistance;
		double cur = i_ss + (s->current[i] - i_ss) * s->i_decay;
		double tau = s->gain_wheel * cur -
			     s->friction_wheel * clampd(w * s->inv_friction_w_eps, -1.0, 1.0);
		int st = s->motor_stuck[i];
		double inv_j = st ? 0.0 : s->inv_j_wheel;
		double ffx = 0.0, ffy = 0.0;

		s->current[i] = cur;
		if (!cfg->lifted) {
			double sx = r * w - (u - omega * yi), sy = -v;
			double *z = s->tread_m[i], f2, px;

			px = sx +
			     dt * r * tau * inv_j; /* slip the wheel's torque alone would give */
			ffx = (k_tyre * z[0] + ce * px) * s->inv_den_long[st];
			ffy = (k_tyre * z[1] + ce * sy) * s->inv_den_lat;
			f2 = ffx * ffx + ffy * ffy;
			if (f2 > s->grip_N[i] * s->grip_N[i]) {
				/* sliding: the tread stays at its elastic limit along the force */
				double k = s->grip_N[i] / sqrt(f2);

				ffx *= k;
				ffy *= k;
				z[0] = ffx * s->inv_tyre_k;
				z[1] = ffy * s->inv_tyre_k;
				sliding[i] = true;
			}
			s->slip[i] = sx;
		}
		w_new[i] = st ? 0.0 : w + dt * (tau - r * ffx) * inv_j;
		s->wheel_w[i] = w_new[i];
		if (!s->motor_enc_cut[i])
			s->motor_pos[i] += s->motor_cnt_per_wheel_step * w_new[i];
		fxb += ffx;
		fyb += ffy;
		torque -= yi * ffx;
	}

	if (!cfg->lifted) {
		double x = s->x, y = s->y;

		fx = fxb * c - fyb * sn;
		fy = fxb * sn + fyb * c;
		if (s->clearance_m <= 0.0) {
			update_clearance(s);
			if (s->clearance_m <= 0.0)
				contact_forces(s, &fx, &fy, &torque);
		}
		vx += dt * fx * s->inv_mass;
		vy += dt * fy * s->inv_mass;
		omega += dt * torque * s->inv_inertia;
		x += dt * vx;
		y += dt * vy;
		s->clearance_m -= dt * (fabs(vx) + fabs(vy));
		dth = dt * omega;
		s->heading += dth;
		if (s->heading > PI)
			s->heading -= 2.0 * PI;
		else if (s->heading <= -PI)
			s->heading += 2.0 * PI;
		dth2 = dth * dth;
		cd = 1.0 - dth2 * (0.5 - dth2 * (1.0 / 24.0));
		sd = dth * (1.0 - dth2 * (1.0 / 6.0));
		fx = c * cd - sn * sd; /* new cosine, sine */
		fy = sn * cd + c * sd;
		c = fx;
		sn = fy;
		s->x = x;
		s->y = y;
		s->vx = vx;
		s->vy = vy;
		s->omega = omega;
		s->cos_h = c;
		s->sin_h = sn;

		u = vx * c + vy * sn;
		v = -vx * sn + vy * c;
		for (i = 0; i < 2; i++) {
			double yi = i == SIM_LEFT ? s->half_track_m : -s->half_track_m;
			double ds = dt * (u - omega * s->enc_y_m[i]); /* [m] */

			/* the tread deflects by the slip that really happened (the implicit force
			 * only predicted it without the walls and the other wheel): no creep under
			 * a steady push */
			if (!sliding[i]) {
				s->tread_m[i][0] += dt * (r * w_new[i] - (u - omega * yi));
				s->tread_m[i][1] -= dt * v;
			}
			s->noise_ds[i] += fabs(ds);
			if (!s->enc_cut[i])
				s->enc_pos[i] += ds * s->enc_cnt_per_m[i];
		}
		/* The noise of variance k |ds| adds up over substeps, so it is drawn once per
		 * NOISE_MASK + 1 substeps for the distance rolled meanwhile: same statistics, a
		 * fraction of the cost (its steps are ~0.01 mm, far below a count). */
		if ((s->steps & NOISE_MASK) == NOISE_MASK)
			add_noise(s);
	}

	s->time_ns += cfg->substep_ns;
	s->steps++;
	if ((s->steps & RESYNC_MASK) == 0) {
		s->cos_h = cos(s->heading);
		s->sin_h = sin(s->heading);
	}
}

void sim_advance_ns(struct sim *s, uint64_t duration_ns)
{
	uint64_t total = s->carry_ns + duration_ns;
	uint64_t n = total / s->cfg.substep_ns;

	s->carry_ns = total % s->cfg.substep_ns;
	while (n--)
		sim_step(s);
}

static int64_t counts(double pos)
{
	int64_t k = (int64_t)pos; /* toward zero; floor is one less for negative non-integers */

	return (double)k > pos ? k - 1 : k;
}

static void to_field(const struct sim *s, const struct sim_point *p, double *x, double *y)
{
	*x = 1000.0 * s->x + p->x_mm * s->cos_h - p->y_mm * s->sin_h;
	*y = 1000.0 * s->y + p->x_mm * s->sin_h + p->y_mm * s->cos_h;
}

void sim_read_sensors(const struct sim *s, struct sim_sensors *out)
{
	const struct sim_config *cfg = &s->cfg;
	double x, y;
	int i;

	memset(out, 0, sizeof(*out));
	for (i = 0; i < 2; i++) {
		out->enc_total[i] = counts(s->enc_pos[i]);
		out->enc_count[i] = (uint16_t)(uint64_t)out->enc_total[i];
		out->motor_total[i] = counts(s->motor_pos[i]);
		out->motor_count[i] = (uint16_t)(uint64_t)out->motor_total[i];
		double ma = 1000.0 * s->current[i];

		out->current_mA[i] = (int32_t)(ma >= 0.0 ? ma + 0.5 : ma - 0.5);
	}
	for (i = 0; i < cfg->shock_count && s->clearance_m <= 0.0; i++) {
		to_field(s, &cfg->shock[i], &x, &y);
		if (field_distance(&s->field, x, y, FIELD_ALL) <= cfg->shock_range_mm)
			out->shock_mask |= (uint8_t)(1u << i);
	}
	if (cfg->basket_sensor && s->clearance_m <= 0.0) {
		to_field(s, &cfg->basket_sensor_pos, &x, &y);
		out->basket = field_distance(&s->field, x, y, FIELD_BASKETS) <= cfg->shock_range_mm;
	}
	for (i = 0; i < cfg->line_sensor_count; i++) {
		to_field(s, &cfg->line_sensor[i], &x, &y);
		if (field_on_line(&s->field, x, y))
			out->line_mask |= (uint8_t)(1u << i);
	}
}

void sim_get_truth(const struct sim *s, struct sim_truth *out)
{
	double c = s->cos_h, sn = s->sin_h;
	int i;

	memset(out, 0, sizeof(*out));
	out->pose.x_mm = 1000.0 * s->x;
	out->pose.y_mm = 1000.0 * s->y;
	out->pose.heading_rad = s->heading;
	out->odo_pose = out->pose;
	out->odo_pose.x_mm += 1000.0 * s->enc_offset_x_m * c;
	out->odo_pose.y_mm += 1000.0 * s->enc_offset_x_m * sn;
	/* the true encoder axis midpoint moves sideways if the two true half-tracks differ: they
	 * do not (the track error is symmetric), so the midpoint is on the robot's x axis */
	out->vx_mm_s = 1000.0 * s->vx;
	out->vy_mm_s = 1000.0 * s->vy;
	out->v_mm_s = 1000.0 * (s->vx * c + s->vy * sn);
	out->v_lateral_mm_s = 1000.0 * (-s->vx * sn + s->vy * c);
	out->omega_rad_s = s->omega;
	for (i = 0; i < 2; i++) {
		out->wheel_speed_mm_s[i] = 1000.0 * s->r_m * s->wheel_w[i];
		out->slip_mm_s[i] = 1000.0 * s->slip[i];
		out->current_A[i] = s->current[i];
	}
	out->contact_force_N = s->contact_force;
	out->time_ns = s->time_ns;
}

void sim_set_battery_V(struct sim *s, double volts)
{
	s->battery_V = volts;
	s->volts_per_q15 = volts / 32767.0;
	update_volts(s);
}

void sim_set_friction_scale(struct sim *s, int wheel, double scale)
{
	if ((wheel == SIM_LEFT || wheel == SIM_RIGHT) && scale >= 0.0) {
		s->mu_scale[wheel] = scale;
		s->grip_N[wheel] = s->cfg.friction_coeff * scale * s->n_wheel_N;
	}
}

void sim_set_motor_stuck(struct sim *s, int wheel, bool stuck)
{
	if (wheel == SIM_LEFT || wheel == SIM_RIGHT) {
		s->motor_stuck[wheel] = stuck;
		if (stuck)
			s->wheel_w[wheel] = 0.0;
	}
}

void sim_set_encoder_cut(struct sim *s, int wheel, bool cut)
{
	if (wheel == SIM_LEFT || wheel == SIM_RIGHT)
		s->enc_cut[wheel] = cut;
}

void sim_set_motor_encoder_cut(struct sim *s, int wheel, bool cut)
{
	if (wheel == SIM_LEFT || wheel == SIM_RIGHT)
		s->motor_enc_cut[wheel] = cut;
}
