/* Line recalibration (see recal.h and docs/recalibration.md). */
#include "recal.h"

#include "fixmath.h"

#define QUARTER_TURN32 ((uint32_t)1 << 30)
/* 2^32 / (2 pi): turn * 2^32 per rad. */
#define TURN32_PER_RAD 683565276LL

static int line_vertical(const struct recal_line *l)
{
	return l->x0_um == l->x1_um;
}

static int line_usable(const struct recal_line *l)
{
	return (l->x0_um == l->x1_um) != (l->y0_um == l->y1_um) && l->width_um > 0;
}

int recal_init(struct recal *r, const struct recal_config *cfg)
{
	int32_t c;

	if (cfg->n_sensors > RECAL_MAX_SENSORS || cfg->n_lines > RECAL_MAX_LINES ||
	    cfg->max_angle_turn32 >= QUARTER_TURN32 || cfg->width_tol_um < 0 ||
	    cfg->margin_um < 0 || cfg->pair_window_um <= 0 || cfg->bound_um > 100000u ||
	    cfg->pair_bound_um > 100000u || cfg->straight_turn32 >= QUARTER_TURN32)
		return -1;
	for (uint8_t i = 0; i < cfg->n_sensors; i++)
		if (fx_abs32(cfg->sensors[i].x_um) > 1000000 ||
		    fx_abs32(cfg->sensors[i].y_um) > 1000000)
			return -1;
	r->cfg = *cfg;
	fx_sincos(cfg->max_angle_turn32, &r->sin_max_q30, &c);
	r->armed = 0;
	r->last_valid = 0;
	r->crossings = 0;
	r->ignored = 0;
	return 0;
}

/* Where sensor i is on the field when the distance axis read mid_um, the robot being at pose
 * (with sine and cosine sn, cs of its heading) when it read dist_um: straight motion between. */
static void sensor_at(const struct recal *r, uint8_t i, const struct odometry_pose *pose,
		      int32_t sn, int32_t cs, int32_t back_um, int32_t *x, int32_t *y)
{
	int64_t ox = r->cfg.sensors[i].x_um, oy = r->cfg.sensors[i].y_um;
	int64_t ahead = ox - back_um; /* the sensor's offset along the heading, at that instant */

	*x = pose->x_um + (int32_t)fx_shr_round64(ahead * cs - oy * sn, 30);
	*y = pose->y_um + (int32_t)fx_shr_round64(ahead * sn + oy * cs, 30);
}

/* The signed distance of (x, y) from line l's centre line, across it [um], or 0 with *near = 0
 * when (x, y) is farther than reach from the segment. */
static int32_t across(const struct recal_line *l, int32_t x, int32_t y, int32_t reach, int *near)
{
	int vertical = line_vertical(l);
	int32_t d = vertical ? x - l->x0_um : y - l->y0_um;
	int32_t a = vertical ? y : x;
	int32_t lo = vertical ? l->y0_um : l->x0_um, hi = vertical ? l->y1_um : l->x1_um;

	if (lo > hi) {
		int32_t t = lo;

		lo = hi;
		hi = t;
	}
	*near = fx_abs32(d) <= reach && a >= lo - reach && a <= hi + reach;
	return d;
}

/* Move the estimate so that sensor i's crossing centre is on line l's centre line. */
static void fix_position(const struct recal *r, uint8_t i, const struct recal_line *l,
			 struct odometry_pose *pose, int32_t back_um)
{
	int32_t sn, cs, x, y, d;
	int near;

	fx_sincos(pose->heading_turn32, &sn, &cs);
	sensor_at(r, i, pose, sn, cs, back_um, &x, &y);
	d = across(l, x, y, INT32_MAX / 2, &near);
	if (line_vertical(l))
		pose->x_um -= d;
	else
		pose->y_um -= d;
}

/* The heading from two sensors' crossings of the same line: i at distance axis s_i, j at s_j.
 * Going straight, sensor k reaches the centre line when (s_k u + R o_k) . n is the same for both:
 * for a line along Y (n = X) that gives tan(heading) = (s_i - s_j + ox_i - ox_j) / (oy_i - oy_j),
 * for a line along X, cot(heading) = -(s_i - s_j + ox_i - ox_j) / (oy_i - oy_j). The quadrant is
 * the estimate's. Returns -1 when the sensors are in line along the heading. */
static int pair_heading(const struct recal *r, const struct recal_line *l, uint8_t i, uint8_t j,
			int32_t s_i, int32_t s_j, int32_t sn, int32_t cs, uint32_t *heading)
{
	int32_t num = (s_i - s_j) + (r->cfg.sensors[i].x_um - r->cfg.sensors[j].x_um);
	int32_t den = r->cfg.sensors[i].y_um - r->cfg.sensors[j].y_um;
	int32_t sy, cx;

	if (den == 0)
		return -1;
	if (line_vertical(l)) {
		sy = num;
		cx = den;
		if ((cx < 0) != (cs < 0)) {
			sy = -sy;
			cx = -cx;
		}
	} else {
		sy = -den;
		cx = num;
		if ((sy < 0) != (sn < 0)) {
			sy = -sy;
			cx = -cx;
		}
	}
	*heading = fx_atan2(sy, cx);
	return 0;
}

/* Sensor i left a line: the crossing from s_in to s_out (distance axis), judged by the rules of
 * recal.h, applied to fix->pose when usable. */
static void crossing(struct recal *r, uint8_t i, int32_t s_in, int32_t s_out, int32_t dist_um,
		     int32_t step_um, const struct uncertainty *u, struct recal_fix *fix)
{
	struct odometry_pose *pose = &fix->pose;
	int32_t travel = s_out - s_in, s_mid = s_in + travel / 2;
	int32_t reach = (int32_t)uncertainty_get_radius_mm(u) * 1000 + r->cfg.margin_um;
	int32_t sn, cs, x, y, crossed, off;
	uint8_t n = 0, best = 0;
	const struct recal_line *l;
	uint32_t heading, hb, turned;
	int near;

	if (travel <= 0) {
		r->ignored++;
		return;
	}
	fx_sincos(pose->heading_turn32, &sn, &cs);
	sensor_at(r, i, pose, sn, cs, dist_um - s_mid, &x, &y);
	for (uint8_t k = 0; k < r->cfg.n_lines; k++) {
		if (!line_usable(&r->cfg.lines[k]))
			continue;
		across(&r->cfg.lines[k], x, y, reach, &near);
		if (near) {
			n++;
			best = k;
		}
	}
	if (n != 1) {
		r->ignored++; /* no known line there, or two: ambiguous */
		return;
	}
	l = &r->cfg.lines[best];
	/* The angle to the normal: the heading's component along the line is its sine. */
	off = line_vertical(l) ? sn : cs;
	crossed =
		(int32_t)fx_shr_round64((int64_t)travel * fx_abs32(line_vertical(l) ? cs : sn), 30);
	if (fx_abs32(off) > r->sin_max_q30 ||
	    fx_abs32(crossed - l->width_um) > r->cfg.width_tol_um) {
		r->ignored++;
		return;
	}

	/* A pair with the other sensor's crossing of the same line gives the heading: applied
	 * when it is known better than the estimate's, before the position. */
	hb = 0;
	turned = fx_angle_dist(pose->heading_turn32, r->last_entry_heading_turn32);
	if (fx_angle_dist(pose->heading_turn32, r->entry_heading_turn32[i]) > turned)
		turned = fx_angle_dist(pose->heading_turn32, r->entry_heading_turn32[i]);
	if (r->last_valid && r->last_line == best && r->last_sensor != i &&
	    turned <= r->cfg.straight_turn32 &&
	    fx_abs32(s_mid - r->last_mid_um) <= r->cfg.pair_window_um &&
	    pair_heading(r, l, i, r->last_sensor, s_mid, r->last_mid_um, sn, cs, &heading) == 0 &&
	    fx_angle_dist(heading, pose->heading_turn32) <= r->cfg.max_angle_turn32) {
		int64_t base =
			fx_abs32(r->cfg.sensors[i].y_um - r->cfg.sensors[r->last_sensor].y_um);
		int64_t err_um = (int64_t)fx_abs32(step_um) + r->cfg.pair_bound_um;

		/* The pair assumes a straight path between the crossings: what the heading turned
		 * meanwhile is added to the bound. */
		hb = (uint32_t)((err_um * TURN32_PER_RAD + base - 1) / base) + turned;
		if (hb < uncertainty_get_heading_bound_turn32(u)) {
			pose->heading_turn32 = heading;
			fix->what |= RECAL_FIX_HEADING;
			fix->heading_bound_turn32 = hb;
		}
	}
	fix_position(r, i, l, pose, dist_um - s_mid);
	fix->what |= RECAL_FIX_POSITION;
	fix->normal_turn32 = line_vertical(l) ? 0 : QUARTER_TURN32;
	fix->bound_um = r->cfg.bound_um + (uint32_t)fx_abs32(step_um) / 2;
	fix->line = best;
	r->crossings++;
	r->last_valid = 1;
	r->last_sensor = i;
	r->last_line = best;
	r->last_mid_um = s_mid;
	r->last_entry_heading_turn32 = r->entry_heading_turn32[i];
}

void recal_sense_init(struct recal_sense *s, struct recal_edges *e, int32_t dist_um)
{
	s->on = 0;
	s->prev_dist_um = dist_um;
	e->on = 0;
	e->rose = 0;
	e->fell = 0;
}

void recal_sense(struct recal_sense *s, struct recal_edges *e, uint8_t lines, int32_t dist_um)
{
	uint8_t changed = (uint8_t)((lines ^ s->on) & ((1u << RECAL_MAX_SENSORS) - 1u));
	int32_t step = dist_um - s->prev_dist_um;

	if (changed) {
		int32_t edge_um = s->prev_dist_um + step / 2;

		/* up to the highest sensor that changed */
		for (uint8_t i = 0, bit = 1; changed >= bit; i++, bit = (uint8_t)(bit << 1)) {
			if (!(changed & bit))
				continue;
			if (lines & bit) {
				e->rose |= bit;
				e->rise_um[i] = edge_um;
			} else {
				e->fell |= bit;
				e->fall_um[i] = edge_um;
				e->fall_step_um[i] = step;
			}
		}
	}
	s->on = lines;
	e->on = lines;
	s->prev_dist_um = dist_um;
}

/* Sensor i entered a line at rise_um. */
static void entry(struct recal *r, uint8_t i, int32_t rise_um, uint32_t heading_turn32)
{
	r->entry_um[i] = rise_um;
	r->entry_heading_turn32[i] = heading_turn32;
	r->armed |= (uint8_t)(1u << i);
}

/* Sensor i left a line: a crossing if its entry was seen. */
static void exit_line(struct recal *r, uint8_t i, const struct recal_edges *e, int32_t dist_um,
		      const struct uncertainty *u, struct recal_fix *fix)
{
	uint8_t bit = (uint8_t)(1u << i);

	if (!(r->armed & bit))
		return;
	r->armed &= (uint8_t)~bit;
	crossing(r, i, r->entry_um[i], e->fall_um[i], dist_um, e->fall_step_um[i], u, fix);
}

void recal_take(struct recal *r, struct recal_edges *e, int enabled,
		const struct odometry_pose *pose, int32_t dist_um, const struct uncertainty *u,
		struct recal_fix *fix)
{
	fix->what = 0;
	fix->pose = *pose;
	if (!enabled) {
		r->armed = 0;
		r->last_valid = 0;
	} else if (e->rose | e->fell) {
		for (uint8_t i = 0; i < r->cfg.n_sensors; i++) {
			uint8_t bit = (uint8_t)(1u << i);

			/* Both in one period: the sensor's state at its end gives their order. */
			if ((e->rose & e->fell & bit) && (e->on & bit)) {
				exit_line(r, i, e, dist_um, u, fix);
				entry(r, i, e->rise_um[i], pose->heading_turn32);
			} else if (e->rose & e->fell & bit) {
				entry(r, i, e->rise_um[i], pose->heading_turn32);
				exit_line(r, i, e, dist_um, u, fix);
			} else if (e->rose & bit) {
				entry(r, i, e->rise_um[i], pose->heading_turn32);
			} else if (e->fell & bit) {
				exit_line(r, i, e, dist_um, u, fix);
			}
		}
	}
	e->rose = 0;
	e->fell = 0;
}
