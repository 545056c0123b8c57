/* Dynamics of the simulated robot: motors, wheels on the table, body, encoders and sensors.
 *
 * Numerical method, one substep of dt (100 us by default; 1 ms, cfg.coarse_substep_ns, for a
 * whole control tick when the robot cannot reach a contact within it, sim_advance_ns(): the
 * penalty walls are the only stiff explicit part, the others stay stable, stable_free(); and
 * only while the tyres stayed within 90 % of their grip in the last call and no contact was
 * looked at in the last 0.5 s: the stick and slide of a tread, a rebound and the stop after a
 * shock are resolved at 100 us. The long substep is first order like the short one: on the
 * open floor it ends moves within 0.2 mm and 0.2 degree of 10 us substeps, the short one
 * within 0.02 mm and 0.02 degree; python/tests/test_sim_coarse.py):
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
 *   5. Body: semi-implicit Euler (velocities first, then positions with the new velocities),
 *      the velocity carried in the body frame (run_ground() says why). The heading's cosine and
 *      sine are rotated incrementally (a 4th-order exact rotation) and recomputed from the
 *      heading every 1024 substeps, so there is no libm call in the common path.
 *   6. Encoders: each free wheel rolls the ground distance of its contact point along the robot
 *      axis, plus noise of variance k |ds| (Chong & Kleeman 1997), converted with its true radius;
 *      motor encoders integrate the shaft angle. Both are sums over the substeps, added to the
 *      positions once per call (add_travel()). Counts are the floor of the continuous position.
 *
 * Sensors: the shock and basket switches are only looked at within reach of something (the
 * clearance, counted down by the distance travelled); the line sensors are computed again only
 * when one has moved farther than its distance to the nearest edge of a line (update_lines()).
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
#define NOISE_SHIFT 4 /* a noise draw every 16 substeps */
/* Coulomb friction of the motor is regularised below this motor speed [rad/s] */
#define MOTOR_FRICTION_W_EPS 2.0
/* The long substep is used only this far from any contact [m], plus what the robot could cover
 * in the call at its speed plus this [m/s] */
#define COARSE_MARGIN_M 0.005
#define COARSE_SPEED_MARGIN 1.0
/* ... and only while no tyre asked for more than this share of its grip in the last call: near
 * the grip (hard braking, a wheel that starts to slide), the short substep resolves when the
 * tread sticks and slides */
#define COARSE_GRIP_SHARE 0.9
#define FINE_AFTER_CONTACT_NS 500000000u

/* Draws the accumulated encoder noise (see add_travel()) into the encoder positions: variance
 * k |ds| [mm^2] for |ds| = noise_cnt / enc_cnt_per_m [m] rolled, noise_var_cnt * noise_cnt
 * [counts^2]. */
static void add_noise(struct sim *s)
{
	int i;

	for (i = 0; i < 2; i++) {
		if (s->noise_var_cnt[i] > 0.0 && s->noise_cnt[i] > 0.0 && !s->enc_cut[i])
			s->enc_pos[i] += sqrt(s->noise_var_cnt[i] * s->noise_cnt[i]) *
					 sim_rng_gauss(&s->rng);
		s->noise_cnt[i] = 0.0;
	}
}

/* The clearance at (x, y) [m]: distance from the drive axis midpoint to the nearest border or
 * obstacle, less the reach of the outline and switches (<= 0: contacts must be computed). */
static double clearance_at(struct sim *s, double x, double y)
{
	double clear =
		1e-3 * field_distance(&s->field, 1000.0 * x, 1000.0 * y, FIELD_ALL) - s->reach_m;

	if (clear > 0.0)
		s->contact_force = 0.0;
	else
		s->fine_until_ns = s->time_ns + FINE_AFTER_CONTACT_NS;
	return clear;
}

/* v clamped to [lo, hi], written as a max then a min so that it compiles to two instructions. */
static double clampd(double v, double lo, double hi)
{
	double t = v > lo ? v : lo;

	return t < hi ? t : hi;
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

/* The explicit parts away from the contacts (the motor friction, the coupling of the wheels
 * through the yaw) are stable at the current substep s->dt_s. */
static bool stable_free(const struct sim *s)
{
	double dt = s->dt_s;
	double cross = s->inv_mass - s->half_track_m * s->half_track_m * s->inv_inertia;

	return s->friction_wheel * s->inv_friction_w_eps * dt * s->inv_j_wheel <= 1.0 &&
	       s->c_eff * dt * fabs(cross) <= 0.5;
}

/* The explicit parts must stay well inside their stability region (eigenvalue * dt < 0.5 for
 * the oscillators, < 1 for the dampers), with up to four contacts at once. */
static int check_stability(const struct sim *s)
{
	double dt = s->dt_s, m_eff, k = s->cfg.wall_stiffness_N_m, r2 = 0.0;
	int i;

	for (i = 0; i < 4; i++)
		r2 = fmax(r2, s->corner_m[i][0] * s->corner_m[i][0] +
				      s->corner_m[i][1] * s->corner_m[i][1]);
	m_eff = 1.0 / (s->inv_mass + r2 * s->inv_inertia);
	if (dt * sqrt(4.0 * k / m_eff) > 0.5)
		return -SIM_EINVAL;
	if (4.0 * s->cfg.wall_damping_N_s_m * dt / m_eff > 1.0)
		return -SIM_EINVAL;
	return stable_free(s) ? 0 : -SIM_EINVAL;
}

/* The coefficients of one wheel in run_substeps(), from the constants of sim_init() and the
 * fault settings: a stuck motor has no inertia to give (and its wheel does not turn), a cut
 * encoder counts nothing. */
static void derive_wheel(struct sim *s, int i)
{
	int st = s->motor_stuck[i];
	double inv_j = st ? 0.0 : s->inv_j_wheel;

	s->px_per_tau[i] = s->dt_s * s->r_m * inv_j;
	s->f_per_tau[i] = s->px_per_tau[i] * s->c_eff * s->inv_den_long[st];
	s->w_per_tau[i] = s->dt_s * inv_j;
	s->f_per_tread_long[i] = s->cfg.tyre_stiffness_N_m * s->inv_den_long[st];
	s->f_per_slip_long[i] = s->c_eff * s->inv_den_long[st];
	s->motor_cnt_per_w[i] = s->motor_enc_cut[i] ? 0.0 : s->motor_cnt_per_wheel_step;
	s->enc_cnt_per_u[i] = s->enc_cut[i] ? 0.0 : s->dt_s * s->enc_cnt_per_m[i];
	s->enc_cnt_per_omega[i] = s->enc_cnt_per_u[i] * s->enc_y_m[i];
	s->noise_var_cnt[i] = 1e-6 * s->cfg.enc_noise_mm2_per_m[i] * s->enc_cnt_per_m[i];
}

static void update_volts(struct sim *s);

/* Every coefficient that depends on the substep, for s->dt_s and s->coarse (the implicit tyre
 * force, the current, the body and the encoders): at init, and when run_substeps() changes
 * between the short substep near contacts and the long one away from them. */
static void derive_step(struct sim *s)
{
	const struct sim_config *cfg = &s->cfg;
	double dt = s->dt_s;
	int i;

	s->i_decay = s->step_decay[s->coarse];
	s->c_eff = cfg->slip_damping_N_s_m + cfg->tyre_stiffness_N_m * dt;
	for (i = 0; i < 2; i++)
		s->inv_den_long[i] = 1.0 / (1.0 + s->c_eff * dt * s->a_long[i]);
	s->inv_den_lat = 1.0 / (1.0 + s->c_eff * dt * s->a_lat);
	/* i' = i_ss + (i - i_ss) decay with i_ss = (u - Ke w) / R, as i decay + in - w per_w */
	s->cur_decay = s->i_decay;
	s->cur_per_w = s->ke_wheel * s->inv_resistance * (1.0 - s->i_decay);
	s->f_per_tread_lat = cfg->tyre_stiffness_N_m * s->inv_den_lat;
	s->f_per_slip_lat = s->c_eff * s->inv_den_lat;
	s->v_per_f = dt * s->inv_mass;
	s->omega_per_torque = dt * s->inv_inertia;
	s->omega_per_dfx = s->half_track_m * s->omega_per_torque;
	s->motor_cnt_per_wheel_step = dt * s->motor_cnt_per_rad;
	for (i = 0; i < 2; i++)
		derive_wheel(s, i);
	update_volts(s);
}

int sim_init(struct sim *s, const struct sim_config *cfg, const struct sim_field *field)
{
	const struct sim_motor_config *m = &cfg->motor;
	double n = m->gear_ratio, hl, hw, ox, oy;
	int i, err;

	memset(s, 0, sizeof(*s));
	s->step_units = 1;
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
	for (i = 0; i < 2; i++) {
		double dt = i ? cfg->coarse_substep_ns * 1e-9 : s->dt_s;

		s->step_decay[i] =
			m->inductance_mH > 0.0
				? exp(-dt * m->resistance_ohm / (m->inductance_mH * 1e-3))
				: 0.0;
	}
	s->i_decay = s->step_decay[0];
	s->gain_wheel = m->gear_efficiency * n * s->kt;
	/* the friction is on the motor shaft, before the gearbox losses */
	s->friction_wheel = m->gear_efficiency * n * m->friction_mNm * 1e-3;
	s->inv_friction_w_eps = n / MOTOR_FRICTION_W_EPS;
	s->inv_tyre_k = 1.0 / cfg->tyre_stiffness_N_m;
	for (i = 0; i < 2; i++) {
		double inv_j = i ? 0.0 : s->inv_j_wheel; /* a stuck wheel has no inertia to give */

		s->a_long[i] = s->r_m * s->r_m * inv_j + s->inv_mass +
			       s->half_track_m * s->half_track_m * s->inv_inertia;
	}
	/* both wheels see the same lateral slip (they are on the y axis) and push the same mass */
	s->a_lat = 2.0 * s->inv_mass;
	for (i = 0; i < 2; i++) {
		double true_r = cfg->enc_radius_mm * (1.0 + cfg->enc_radius_error[i]);
		double side = i == SIM_LEFT ? 1.0 : -1.0;

		s->enc_y_m[i] = side * 0.5e-3 * (cfg->enc_track_mm + cfg->enc_track_error_mm);
		s->enc_cnt_per_m[i] = 1000.0 * cfg->enc_cpr / (2.0 * PI * true_r);
		sim_set_friction_scale(s, i, 1.0);
	}
	s->motor_cnt_per_rad = n * m->encoder_cpr / (2.0 * PI);
	s->enc_offset_x_m = cfg->enc_offset_x_mm * 1e-3;

	field_line_boxes(&s->field, &s->line_box[0][0]);
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

	s->friction_per_w = s->friction_wheel * s->inv_friction_w_eps;
	derive_step(s);
	err = check_stability(s);
	if (err)
		return err;
	/* The long substep, away from contacts: only if its explicit parts are stable too (the
	 * contacts are never integrated with it) */
	s->coarse_ns = cfg->coarse_substep_ns;
	if (s->coarse_ns > cfg->substep_ns) {
		s->coarse = 1;
		s->dt_s = s->coarse_ns * 1e-9;
		derive_step(s);
		if (!stable_free(s))
			s->coarse_ns = 0;
		s->coarse = 0;
		s->dt_s = cfg->substep_ns * 1e-9;
		derive_step(s);
	} else {
		s->coarse_ns = 0;
	}

	sim_set_battery_V(s, cfg->battery_V);
	sim_rng_seed(&s->rng, cfg->seed);
	sim_set_pose(s, &cfg->start);
	return 0;
}

static void update_lines(struct sim *s);

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
	s->grip_use2 = 0.0;
	memset(s->tread_m, 0, sizeof(s->tread_m));
	s->contact_force = 0.0;
	s->clearance_m = 0.0;    /* look again */
	s->line_margin_mm = 0.0; /* likewise */
	update_lines(s);
}

static void update_volts(struct sim *s)
{
	int i;

	for (i = 0; i < 2; i++) {
		s->volts[i] = s->duty_q15[i] * s->volts_per_q15;
		s->cur_in[i] = s->volts[i] * s->inv_resistance * (1.0 - s->i_decay);
	}
}

void sim_set_duty(struct sim *s, int16_t left_q15, int16_t right_q15)
{
	s->duty_q15[SIM_LEFT] = left_q15 < -32767 ? -32767 : left_q15;
	s->duty_q15[SIM_RIGHT] = right_q15 < -32767 ? -32767 : right_q15;
	update_volts(s);
}

/* Adds the forces of the borders and obstacles on the outline to the body-frame force f[0],
 * f[1] [N] and the yaw rate step f[2] [rad/s] of a substep. The body is at (x, y) [m], heading
 * (c, sn), moving at (u, v) [m/s] in its own frame, turning at omega [rad/s]. */
static void contact_forces(struct sim *s, double x, double y, double c, double sn, double u,
			   double v, double omega, double f[3])
{
	struct field_contact ct[FIELD_MAX_CONTACTS];
	struct field_rect r;
	const struct sim_config *cfg = &s->cfg;
	double ox = cfg->outline_offset_x_mm, oy = cfg->outline_offset_y_mm;
	double vx = c * u - sn * v, vy = sn * u + c * v;
	double fx = 0.0, fy = 0.0, torque = 0.0, total = 0.0;
	int i, n;

	r.cx = 1000.0 * x + ox * c - oy * sn;
	r.cy = 1000.0 * y + ox * sn + oy * c;
	r.ux = c;
	r.uy = sn;
	r.half_len = 0.5 * cfg->outline_length_mm;
	r.half_wid = 0.5 * cfg->outline_width_mm;
	r.bound = 1000.0 * s->bound_radius_m;
	n = field_collide(&s->field, &r, ct);
	for (i = 0; i < n; i++) {
		double rx = 1e-3 * ct[i].px - x, ry = 1e-3 * ct[i].py - y;
		double vpx = vx - omega * ry, vpy = vy + omega * rx;
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
		fx += px;
		fy += py;
		torque += rx * py - ry * px;
		total += fn;
	}
	f[0] += c * fx + sn * fy;
	f[1] += -sn * fx + c * fy;
	f[2] += torque * s->omega_per_torque;
	s->contact_force = total;
}

/* Step 1 for one wheel: the current, exact for the frozen speed, and the motor torque at the
 * wheel [N m] that steps 2 and 3 use. */
static double motor_torque(const struct sim *s, int i, double w, double *cur)
{
	*cur = *cur * s->cur_decay + (s->cur_in[i] - w * s->cur_per_w);
	return s->gain_wheel * *cur -
	       clampd(w * s->friction_per_w, -s->friction_wheel, s->friction_wheel);
}

/* The wheel and motor encoder travel of a call, added once at its end [counts]: the sums over
 * its substeps of the forward speed, yaw rate and wheel speeds, times the counts per unit. The
 * free wheel noise is drawn once per 2^NOISE_SHIFT substeps for the distance rolled meanwhile
 * (its variance k |ds| adds up, so the statistics are those of a draw per substep, at a
 * fraction of the cost); a call's travel counts toward the draw its last substep falls in. */
static void add_travel(struct sim *s, uint64_t steps_before, double sum_u, double sum_omega,
		       const double sum_w[2])
{
	int i;

	for (i = 0; i < 2; i++) {
		double inc = sum_u * s->enc_cnt_per_u[i] - sum_omega * s->enc_cnt_per_omega[i];

		s->enc_pos[i] += inc;
		s->noise_cnt[i] += fabs(inc);
		s->motor_pos[i] += sum_w[i] * s->motor_cnt_per_w[i];
	}
	if ((steps_before >> NOISE_SHIFT) != (s->steps >> NOISE_SHIFT))
		add_noise(s);
}

/* The line sensors depend on their position only: the mask is kept with the positions it was
 * computed at and a margin that none of them can move without the answer changing, and only
 * computed again when a sensor moved farther than that (every few centimetres of travel,
 * instead of every read). */
static void update_lines(struct sim *s)
{
	const struct sim_config *cfg = &s->cfg;
	double xm = 1000.0 * s->x, ym = 1000.0 * s->y, p[SIM_MAX_LINE_SENSORS][2];
	double m2 = s->line_margin_mm * s->line_margin_mm;
	bool moved = false;
	int i;

	for (i = 0; i < cfg->line_sensor_count; i++) {
		const struct sim_point *q = &cfg->line_sensor[i];
		double dx, dy;

		p[i][0] = xm + q->x_mm * s->cos_h - q->y_mm * s->sin_h;
		p[i][1] = ym + q->x_mm * s->sin_h + q->y_mm * s->cos_h;
		dx = p[i][0] - s->line_ref_mm[i][0];
		dy = p[i][1] - s->line_ref_mm[i][1];
		moved |= !(dx * dx + dy * dy < m2);
	}
	if (!moved)
		return;
	s->line_mask = 0;
	s->line_margin_mm = 1e9;
	for (i = 0; i < cfg->line_sensor_count; i++) {
		double margin;

		if (field_on_line(&s->field, &s->line_box[0][0], p[i][0], p[i][1], &margin))
			s->line_mask |= (uint8_t)(1u << i);
		if (margin < s->line_margin_mm)
			s->line_margin_mm = margin;
		s->line_ref_mm[i][0] = p[i][0];
		s->line_ref_mm[i][1] = p[i][1];
	}
}

/* n substeps of a robot on a stand: the wheels turn freely, nothing else moves. */
static void run_lifted(struct sim *s, uint64_t n)
{
	double sum_w[2] = {0.0, 0.0};
	uint64_t steps = s->steps;
	int i;

	for (; n > 0; n--) {
		for (i = 0; i < 2; i++) {
			double tau = motor_torque(s, i, s->wheel_w[i], &s->current[i]);

			s->wheel_w[i] += tau * s->w_per_tau[i];
			sum_w[i] += s->wheel_w[i];
		}
		s->steps++;
	}
	add_travel(s, steps, 0.0, 0.0, sum_w);
}

/* n substeps on the ground (the numbered steps of the method at the top of this file). The
 * state lives in local variables for the whole call, so that it stays in registers, and is
 * written back at the end. The body's velocity is kept in the body frame (u forward, v to the
 * left) during the call: the semi-implicit step adds the force in the old frame, p, q = u, v +
 * dt F / m, moves the position by R(heading) (p, q) dt, and turns p, q by -dth into the new
 * frame: the same step as in the field frame, but the speeds the tyres need come out of it
 * directly, which keeps the chain of dependent operations from one substep to the next short.
 * The heading's cosine and sine are carried times dt (cdt, sdt), as the position step uses
 * them. What a substep computes for the next (the slip of each wheel) is carried. A stuck motor
 * or a cut encoder is a zero coefficient (derive_wheel()), not a branch. */
static void run_ground(struct sim *s, uint64_t n)
{
	const double dt = s->dt_s, r = s->r_m, ht = s->half_track_m;
	double x = s->x, y = s->y, cdt = s->cos_h * dt, sdt = s->sin_h * dt, omega = s->omega;
	double u = s->vx * s->cos_h + s->vy * s->sin_h, v = -s->vx * s->sin_h + s->vy * s->cos_h;
	double clear = s->clearance_m, dheading = 0.0, sum_u = 0.0;
	double w0 = s->wheel_w[0], w1 = s->wheel_w[1], cur0 = s->current[0], cur1 = s->current[1];
	double z00 = s->tread_m[0][0], z01 = s->tread_m[0][1];
	double z10 = s->tread_m[1][0], z11 = s->tread_m[1][1];
	double sx0 = (r * w0 + omega * ht) - u, sx1 = (r * w1 - omega * ht) - u;
	double sum_w0 = 0.0, sum_w1 = 0.0, sum_w[2], grip_use = 0.0;
	const uint64_t inc = s->step_units;
	uint64_t steps = s->steps;

	for (; n > 0; n--) {
		/* 1. motor currents and torques */
		double tau0 = motor_torque(s, 0, w0, &cur0);
		double tau1 = motor_torque(s, 1, w1, &cur1);
		/* 2. tyre forces, linearly implicit, capped by the friction circle */
		double vlat = v * s->f_per_slip_lat;
		double fx0 = (z00 * s->f_per_tread_long[0] + tau0 * s->f_per_tau[0]) +
			     sx0 * s->f_per_slip_long[0];
		double fx1 = (z10 * s->f_per_tread_long[1] + tau1 * s->f_per_tau[1]) +
			     sx1 * s->f_per_slip_long[1];
		double fy0 = z01 * s->f_per_tread_lat - vlat;
		double fy1 = z11 * s->f_per_tread_lat - vlat;
		double fxb, fyb, domega, p, q, dx, dy, dth, dth2, cd, sd, nc, hw;
		double f2_0 = fx0 * fx0 + fy0 * fy0, f2_1 = fx1 * fx1 + fy1 * fy1;
		int slide0 = f2_0 > s->grip2_N2[0];
		int slide1 = f2_1 > s->grip2_N2[1];

		/* the largest share of the grip a tyre asked for (squared, times the grip squared
		 * of the other wheel: no division in the loop), for the choice of the substep */
		grip_use = fmax(grip_use, fmax(f2_0 * s->grip2_N2[1], f2_1 * s->grip2_N2[0]));

		if (slide0) {
			/* sliding: the tread stays at its elastic limit along the force */
			double k = s->grip_N[0] / sqrt(fx0 * fx0 + fy0 * fy0);

			fx0 *= k;
			fy0 *= k;
			z00 = fx0 * s->inv_tyre_k;
			z01 = fy0 * s->inv_tyre_k;
		}
		if (slide1) {
			double k = s->grip_N[1] / sqrt(fx1 * fx1 + fy1 * fy1);

			fx1 *= k;
			fy1 *= k;
			z10 = fx1 * s->inv_tyre_k;
			z11 = fy1 * s->inv_tyre_k;
		}
		/* 3. wheel speeds */
		w0 += tau0 * s->w_per_tau[0] - fx0 * s->px_per_tau[0];
		w1 += tau1 * s->w_per_tau[1] - fx1 * s->px_per_tau[1];
		sum_w0 += w0;
		sum_w1 += w1;

		/* 4. contacts, only within reach of something */
		fxb = fx0 + fx1;
		fyb = fy0 + fy1;
		domega = (fx1 - fx0) * s->omega_per_dfx;
		if (clear <= 0.0) {
			clear = clearance_at(s, x, y);
			if (clear <= 0.0) {
				/* (through copies: the addresses of the hot variables would keep
				 * them out of registers) */
				double f[3] = {fxb, fyb, domega};

				contact_forces(s, x, y, cdt / dt, sdt / dt, u, v, omega, f);
				fxb = f[0];
				fyb = f[1];
				domega = f[2];
			}
		}
		/* 5. body: velocities, then positions with the new velocities, then the new frame:
		 * the heading's cosine and sine turned by the exact rotation to 4th order */
		p = u + fxb * s->v_per_f;
		q = v + fyb * s->v_per_f;
		omega += domega;
		dx = cdt * p - sdt * q;
		dy = sdt * p + cdt * q;
		x += dx;
		y += dy;
		clear -= fabs(dx) + fabs(dy);
		dth = dt * omega;
		dheading += dth;
		dth2 = dth * dth;
		cd = (1.0 - 0.5 * dth2) + dth2 * dth2 * (1.0 / 24.0);
		sd = dth * (1.0 - dth2 * (1.0 / 6.0));
		nc = cdt * cd - sdt * sd;
		sdt = sdt * cd + cdt * sd;
		cdt = nc;
		u = cd * p + sd * q;
		v = cd * q - sd * p;
		steps += inc;
		if ((steps & RESYNC_MASK) < inc) {
			cdt = cos(s->heading + dheading) * dt;
			sdt = sin(s->heading + dheading) * dt;
		}
		sum_u += u;
		/* 6. the tread deflects by the slip that really happened (the implicit force only
		 * predicted it without the walls and the other wheel): no creep under a steady
		 * push */
		hw = omega * ht;
		sx0 = (r * w0 + hw) - u;
		sx1 = (r * w1 - hw) - u;
		if (!slide0) {
			z00 += dt * sx0;
			z01 -= dt * v;
		}
		if (!slide1) {
			z10 += dt * sx1;
			z11 -= dt * v;
		}
	}

	s->x = x;
	s->y = y;
	s->heading = wrap_pi(s->heading + dheading);
	s->cos_h = cdt / dt;
	s->sin_h = sdt / dt;
	s->vx = s->cos_h * u - s->sin_h * v;
	s->vy = s->sin_h * u + s->cos_h * v;
	s->omega = omega;
	s->clearance_m = clear;
	s->wheel_w[0] = w0;
	s->wheel_w[1] = w1;
	s->current[0] = cur0;
	s->current[1] = cur1;
	s->tread_m[0][0] = z00;
	s->tread_m[0][1] = z01;
	s->tread_m[1][0] = z10;
	s->tread_m[1][1] = z11;
	s->slip[0] = sx0;
	s->slip[1] = sx1;
	s->grip_use2 = grip_use;
	n = s->steps;
	s->steps = steps;
	sum_w[0] = sum_w0;
	sum_w[1] = sum_w1;
	add_travel(s, n, sum_u, dheading / dt, sum_w);
	update_lines(s);
}

/* Changes to the long substep (coarse = 1) or back to the short one. */
static void set_step(struct sim *s, int coarse)
{
	if (s->coarse == coarse)
		return;
	s->coarse = coarse;
	s->dt_s = (coarse ? s->coarse_ns : s->cfg.substep_ns) * 1e-9;
	s->step_units = coarse ? s->coarse_ns / s->cfg.substep_ns : 1;
	derive_step(s);
}

static void run_substeps(struct sim *s, uint64_t n)
{
	set_step(s, 0);
	s->time_ns += n * s->cfg.substep_ns;
	s->short_steps += n;
	if (s->cfg.lifted)
		run_lifted(s, n);
	else
		run_ground(s, n);
}

void sim_step(struct sim *s)
{
	run_substeps(s, 1);
}

/* True if a disc of radius r [mm] at (x, y) [mm] overlaps the robot's outline. */
static bool disc_on_robot(const struct sim *s, double x, double y, double r)
{
	const struct sim_config *cfg = &s->cfg;
	double hl = 0.5 * cfg->outline_length_mm, hw = 0.5 * cfg->outline_width_mm;
	double rx = x - 1000.0 * s->x, ry = y - 1000.0 * s->y;
	double lx = rx * s->cos_h + ry * s->sin_h - cfg->outline_offset_x_mm;
	double ly = -rx * s->sin_h + ry * s->cos_h - cfg->outline_offset_y_mm;
	double dx = fabs(lx) - hl, dy = fabs(ly) - hw;

	dx = dx > 0.0 ? dx : 0.0;
	dy = dy > 0.0 ? dy : 0.0;
	return dx * dx + dy * dy < r * r;
}

/* Moves opponent k by the distance it covers in duration_ns along its path; the robot's
 * clearance shrinks by as much (an upper bound of the distance moved). An opponent does not
 * move into the robot: it waits where it touched it (an immovable obstacle pressed on the
 * robot would crush it against the border), as a robot stopped by its own shock switches. */
static void move_opponent(struct sim *s, struct sim_opponent *p, uint64_t duration_ns)
{
	struct sim_obstacle *o = &s->field.obstacles[p->obstacle];
	double left = p->speed_mm_s * (double)duration_ns * 1e-9;
	double x = o->x_mm, y = o->y_mm;
	int guard = 2 * SIM_MAX_PATH + 2; /* a loop of points closer than the step ends too */

	while (left > 0.0 && p->n_points > 0 && guard-- > 0) {
		double tx = p->path_mm[p->next][0], ty = p->path_mm[p->next][1];
		double dx = tx - x, dy = ty - y, seg = sqrt(dx * dx + dy * dy);

		if (seg > left) {
			x += dx * (left / seg);
			y += dy * (left / seg);
			break;
		}
		x = tx;
		y = ty;
		left -= seg;
		if (++p->next >= p->n_points) {
			p->next = 0;
			if (!p->loop)
				p->n_points = 0; /* arrived: it stands there */
		}
	}
	{
		double r =
			o->shape == SIM_SHAPE_CIRCLE
				? o->radius_mm
				: sqrt(o->half_x_mm * o->half_x_mm + o->half_y_mm * o->half_y_mm);

		if (disc_on_robot(s, x, y, r) && !disc_on_robot(s, o->x_mm, o->y_mm, r))
			return; /* blocked by the robot: it waits, touching it */
	}
	s->clearance_m -= 1e-3 * (fabs(x - o->x_mm) + fabs(y - o->y_mm));
	o->x_mm = x;
	o->y_mm = y;
}

void sim_advance_ns(struct sim *s, uint64_t duration_ns)
{
	uint64_t total = s->carry_ns + duration_ns;
	uint64_t n;
	int k;

	for (k = 0; k < s->opponent_count; k++)
		move_opponent(s, &s->opponents[k], duration_ns);
	/* Away from everything, whole long substeps: the robot cannot reach a contact within the
	 * call (its speed times the duration, plus a margin for what it may gain meanwhile) */
	if (s->coarse_ns && s->carry_ns == 0 && duration_ns % s->coarse_ns == 0 && !s->cfg.lifted) {
		double speed = fabs(s->vx) + fabs(s->vy) + 0.5 * s->half_track_m * fabs(s->omega);
		double reach = (speed + COARSE_SPEED_MARGIN) * (double)duration_ns * 1e-9;

		if (s->clearance_m > reach + COARSE_MARGIN_M && s->grip_use2 < s->coarse_grip2 &&
		    s->time_ns >= s->fine_until_ns) {
			uint64_t m = duration_ns / s->coarse_ns;

			set_step(s, 1);
			s->time_ns += duration_ns;
			s->coarse_steps += m;
			run_ground(s, m);
			return;
		}
	}

	/* A lockstep host asks for the same period every time: the 64-bit division (some tens
	 * of cycles before the first substep can start) is kept with the time it divided. */
	if (total != s->split_ns) {
		s->split_ns = total;
		s->split_n = total / s->cfg.substep_ns;
		s->split_rest_ns = total % s->cfg.substep_ns;
	}
	n = s->split_n;
	s->carry_ns = s->split_rest_ns;
	if (n > 0)
		run_substeps(s, n);
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
	out->line_mask = s->line_mask; /* kept up to date by update_lines() */
	out->shock_mask |= s->shock_forced;
	out->basket = out->basket || s->basket_forced;
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
		s->grip2_N2[wheel] = s->grip_N[wheel] * s->grip_N[wheel];
		s->coarse_grip2 =
			COARSE_GRIP_SHARE * COARSE_GRIP_SHARE * s->grip2_N2[0] * s->grip2_N2[1];
	}
}

void sim_set_motor_stuck(struct sim *s, int wheel, bool stuck)
{
	if (wheel == SIM_LEFT || wheel == SIM_RIGHT) {
		s->motor_stuck[wheel] = stuck;
		if (stuck)
			s->wheel_w[wheel] = 0.0;
		derive_wheel(s, wheel);
	}
}

void sim_set_encoder_cut(struct sim *s, int wheel, bool cut)
{
	if (wheel == SIM_LEFT || wheel == SIM_RIGHT) {
		s->enc_cut[wheel] = cut;
		derive_wheel(s, wheel);
	}
}

void sim_set_motor_encoder_cut(struct sim *s, int wheel, bool cut)
{
	if (wheel == SIM_LEFT || wheel == SIM_RIGHT) {
		s->motor_enc_cut[wheel] = cut;
		derive_wheel(s, wheel);
	}
}

void sim_force_sensors(struct sim *s, uint8_t shock_mask, bool basket)
{
	s->shock_forced = shock_mask;
	s->basket_forced = basket;
}

static bool finite_nonneg(double v)
{
	return v >= 0.0 && v < 1e12;
}

static bool finite_coord(double v)
{
	return v > -1e9 && v < 1e9; /* also rejects NaN */
}

int sim_add_obstacle(struct sim *s, const struct sim_obstacle *o)
{
	int i = s->field.obstacle_count;

	if (i >= SIM_MAX_OBSTACLES || o->shape > SIM_SHAPE_BOX || o->kind > SIM_OBSTACLE_OTHER ||
	    !finite_nonneg(o->radius_mm) || !finite_nonneg(o->half_x_mm) ||
	    !finite_nonneg(o->half_y_mm) || !finite_coord(o->x_mm) || !finite_coord(o->y_mm) ||
	    !finite_coord(o->heading_rad))
		return -SIM_EINVAL;
	s->field.obstacles[i] = *o;
	s->field.obstacle_count = (uint8_t)(i + 1);
	s->clearance_m = 0.0; /* look again */
	return i;
}

void sim_move_obstacle(struct sim *s, int i, double x_mm, double y_mm, double heading_rad)
{
	struct sim_obstacle *o;

	if (i < 0 || i >= s->field.obstacle_count || !finite_coord(x_mm) || !finite_coord(y_mm) ||
	    !finite_coord(heading_rad))
		return;
	o = &s->field.obstacles[i];
	o->x_mm = x_mm;
	o->y_mm = y_mm;
	o->heading_rad = heading_rad;
	s->clearance_m = 0.0; /* look again */
}

int sim_set_opponent_path(struct sim *s, int i, const double *path_mm, int n, double speed_mm_s,
			  bool loop)
{
	struct sim_opponent *p = NULL;
	int k;

	if (i < 0 || i >= s->field.obstacle_count || n < 0 || n > SIM_MAX_PATH ||
	    !(speed_mm_s > 0.0 && speed_mm_s < 1e6))
		return -SIM_EINVAL;
	for (k = 0; k < 2 * n; k++)
		if (!finite_coord(path_mm[k]))
			return -SIM_EINVAL;
	for (k = 0; k < s->opponent_count; k++)
		if (s->opponents[k].obstacle == i)
			p = &s->opponents[k];
	if (!p) {
		if (s->opponent_count >= SIM_MAX_OPPONENTS)
			return -SIM_EINVAL;
		p = &s->opponents[s->opponent_count++];
	}
	memset(p, 0, sizeof(*p));
	p->obstacle = (uint8_t)i;
	p->n_points = (uint8_t)n;
	p->loop = loop;
	p->speed_mm_s = speed_mm_s;
	for (k = 0; k < n; k++) {
		p->path_mm[k][0] = path_mm[2 * k];
		p->path_mm[k][1] = path_mm[2 * k + 1];
	}
	return 0;
}
