/* The field for the simulator: default layout and the contact geometry of the robot outline with
 * the borders, baskets and lines (all in mm, field frame). */
#include <math.h>
#include <string.h>

#include "field.h"
#include "field_default_gen.h"

void sim_field_defaults(struct sim_field *f)
{
	*f = sim_field_default_gen; /* field/default.toml, through field/gen_field.py */
}

static unsigned kind_mask(const struct sim_obstacle *o)
{
	return o->kind == SIM_OBSTACLE_BASKET ? FIELD_BASKETS : FIELD_OTHERS;
}

static double fmin2(double a, double b)
{
	return a < b ? a : b;
}

static double fmax2(double a, double b)
{
	return a > b ? a : b;
}

static double clamp(double v, double lo, double hi)
{
	return v < lo ? lo : (v > hi ? hi : v);
}

/* (dx, dy) from the field frame into the frame of a box turned by heading_rad (the common
 * axis-aligned box keeps its coordinates, without a libm call). */
static void to_box(const struct sim_obstacle *o, double *dx, double *dy)
{
	double c, sn, x = *dx;

	if (o->heading_rad == 0.0)
		return;
	c = cos(o->heading_rad);
	sn = sin(o->heading_rad);
	*dx = c * x + sn * *dy;
	*dy = -sn * x + c * *dy;
}

/* A direction (nx, ny) from a box's frame back into the field frame. */
static void from_box(const struct sim_obstacle *o, double *nx, double *ny)
{
	double c, sn, x = *nx;

	if (o->heading_rad == 0.0)
		return;
	c = cos(o->heading_rad);
	sn = sin(o->heading_rad);
	*nx = c * x - sn * *ny;
	*ny = sn * x + c * *ny;
}

static double obstacle_distance(const struct sim_obstacle *o, double x, double y)
{
	double dx = x - o->x_mm, dy = y - o->y_mm;

	if (o->shape == SIM_SHAPE_CIRCLE)
		return sqrt(dx * dx + dy * dy) - o->radius_mm;
	to_box(o, &dx, &dy);
	dx = fabs(dx) - o->half_x_mm;
	dy = fabs(dy) - o->half_y_mm;
	if (dx > 0.0 || dy > 0.0) {
		double ox = fmax2(dx, 0.0), oy = fmax2(dy, 0.0);

		return sqrt(ox * ox + oy * oy);
	}
	return fmax2(dx, dy);
}

double field_distance(const struct sim_field *f, double x, double y, unsigned mask)
{
	double d = 1e9;
	int i;

	if ((mask & FIELD_BORDERS) && f->borders)
		d = fmin2(0.5 * f->length_mm - fabs(x), 0.5 * f->width_mm - fabs(y));
	for (i = 0; i < f->obstacle_count; i++) {
		const struct sim_obstacle *o = &f->obstacles[i];

		if (mask & kind_mask(o))
			d = fmin2(d, obstacle_distance(o, x, y));
	}
	return d;
}

void field_line_boxes(const struct sim_field *f, double *box)
{
	int i;

	for (i = 0; i < f->line_count; i++) {
		const struct sim_line *l = &f->lines[i];
		double hw = 0.5 * l->width_mm;

		box[4 * i] = fmin2(l->x0_mm, l->x1_mm) - hw;
		box[4 * i + 1] = fmax2(l->x0_mm, l->x1_mm) + hw;
		box[4 * i + 2] = fmin2(l->y0_mm, l->y1_mm) - hw;
		box[4 * i + 3] = fmax2(l->y0_mm, l->y1_mm) + hw;
	}
}

bool field_on_line(const struct sim_field *f, const double *box, double x, double y, double *margin)
{
	double m = 1e9;
	bool on = false;
	int i;

	for (i = 0; i < f->line_count; i++) {
		const struct sim_line *l = &f->lines[i];
		double hw = 0.5 * l->width_mm;
		const double *b = &box[4 * i];
		double out = fmax2(fmax2(b[0] - x, x - b[1]), fmax2(b[2] - y, y - b[3]));
		double ax, ay, px, py, len2, t, ex, ey, d;

		/* most lines are far: outside the bounding box by out, the point is at least that
		 * far from the line */
		if (out > 0.0) {
			m = fmin2(m, out);
			continue;
		}
		ax = l->x1_mm - l->x0_mm;
		ay = l->y1_mm - l->y0_mm;
		px = x - l->x0_mm;
		py = y - l->y0_mm;
		len2 = ax * ax + ay * ay;
		t = len2 > 0.0 ? clamp((px * ax + py * ay) / len2, 0.0, 1.0) : 0.0;
		ex = px - t * ax;
		ey = py - t * ay;
		d = sqrt(ex * ex + ey * ey);
		if (d <= hw)
			on = true;
		m = fmin2(m, fabs(d - hw));
	}
	*margin = m;
	return on;
}

static int add_contact(struct field_contact *out, int n, double px, double py, double nx, double ny,
		       double depth)
{
	if (n >= FIELD_MAX_CONTACTS)
		return n;
	out[n].px = px;
	out[n].py = py;
	out[n].nx = nx;
	out[n].ny = ny;
	out[n].depth = depth;
	return n + 1;
}

static int collide_borders(const struct sim_field *f, double corner[4][2],
			   struct field_contact *out, int n)
{
	double hx = 0.5 * f->length_mm, hy = 0.5 * f->width_mm;
	int i;

	for (i = 0; i < 4; i++) {
		double x = corner[i][0], y = corner[i][1];

		if (x > hx)
			n = add_contact(out, n, x, y, -1.0, 0.0, x - hx);
		if (x < -hx)
			n = add_contact(out, n, x, y, 1.0, 0.0, -hx - x);
		if (y > hy)
			n = add_contact(out, n, x, y, 0.0, -1.0, y - hy);
		if (y < -hy)
			n = add_contact(out, n, x, y, 0.0, 1.0, -hy - y);
	}
	return n;
}

static int collide_circle(const struct sim_obstacle *o, const struct field_rect *r,
			  struct field_contact *out, int n)
{
	double rx = o->x_mm - r->cx, ry = o->y_mm - r->cy;
	double lx = rx * r->ux + ry * r->uy; /* circle centre in the rectangle's frame */
	double ly = -rx * r->uy + ry * r->ux;
	double qx = clamp(lx, -r->half_len, r->half_len);
	double qy = clamp(ly, -r->half_wid, r->half_wid);
	double dx = lx - qx, dy = ly - qy, d2 = dx * dx + dy * dy;
	double nlx, nly, depth;

	if (d2 > 0.0) {
		double d = sqrt(d2);

		if (d >= o->radius_mm)
			return n;
		nlx = -dx /
		      d; /* from the centre towards the nearest point: the robot goes that way */
		nly = -dy / d;
		depth = o->radius_mm - d;
	} else if (r->half_len - fabs(lx) < r->half_wid - fabs(ly)) {
		/* centre inside the outline (a deep hit): leave through the nearest face */
		nlx = lx > 0.0 ? -1.0 : 1.0;
		nly = 0.0;
		qx = lx > 0.0 ? r->half_len : -r->half_len;
		depth = r->half_len - fabs(lx) + o->radius_mm;
	} else {
		nlx = 0.0;
		nly = ly > 0.0 ? -1.0 : 1.0;
		qy = ly > 0.0 ? r->half_wid : -r->half_wid;
		depth = r->half_wid - fabs(ly) + o->radius_mm;
	}
	return add_contact(out, n, r->cx + qx * r->ux - qy * r->uy, r->cy + qx * r->uy + qy * r->ux,
			   nlx * r->ux - nly * r->uy, nlx * r->uy + nly * r->ux, depth);
}

static int collide_box(const struct sim_obstacle *o, const struct field_rect *r,
		       double corner[4][2], struct field_contact *out, int n)
{
	double hx = o->half_x_mm, hy = o->half_y_mm;
	double ux = 1.0, uy = 0.0; /* the box's x axis in the field frame */
	int i;

	from_box(o, &ux, &uy);
	/* corners of the robot inside the box: pushed out through the nearest face of the box */
	for (i = 0; i < 4; i++) {
		double x = corner[i][0] - o->x_mm, y = corner[i][1] - o->y_mm;
		double px, py, nx, ny;

		to_box(o, &x, &y);
		px = hx - fabs(x);
		py = hy - fabs(y);
		if (px <= 0.0 || py <= 0.0)
			continue;
		nx = px < py ? (x > 0.0 ? 1.0 : -1.0) : 0.0;
		ny = px < py ? 0.0 : (y > 0.0 ? 1.0 : -1.0);
		from_box(o, &nx, &ny);
		n = add_contact(out, n, corner[i][0], corner[i][1], nx, ny, px < py ? px : py);
	}
	/* corners of the box inside the robot: the robot moves away through its nearest face */
	for (i = 0; i < 4; i++) {
		double a = (i & 1) ? hx : -hx, b = (i & 2) ? hy : -hy;
		double bx = o->x_mm + a * ux - b * uy, by = o->y_mm + a * uy + b * ux;
		double rx = bx - r->cx, ry = by - r->cy;
		double lx = rx * r->ux + ry * r->uy, ly = -rx * r->uy + ry * r->ux;
		double px = r->half_len - fabs(lx), py = r->half_wid - fabs(ly);
		double nlx = 0.0, nly = 0.0, depth;

		if (px <= 0.0 || py <= 0.0)
			continue;
		if (px < py) {
			nlx = lx > 0.0 ? -1.0 : 1.0;
			depth = px;
		} else {
			nly = ly > 0.0 ? -1.0 : 1.0;
			depth = py;
		}
		n = add_contact(out, n, bx, by, nlx * r->ux - nly * r->uy,
				nlx * r->uy + nly * r->ux, depth);
	}
	return n;
}

int field_collide(const struct sim_field *f, const struct field_rect *r, struct field_contact *out)
{
	double corner[4][2];
	bool near_border;
	int i, n = 0;

	near_border = f->borders && (fabs(r->cx) + r->bound > 0.5 * f->length_mm ||
				     fabs(r->cy) + r->bound > 0.5 * f->width_mm);
	for (i = 0; i < 4; i++) {
		double a = (i & 1) ? r->half_len : -r->half_len;
		double b = (i & 2) ? r->half_wid : -r->half_wid;

		corner[i][0] = r->cx + a * r->ux - b * r->uy;
		corner[i][1] = r->cy + a * r->uy + b * r->ux;
	}
	if (near_border)
		n = collide_borders(f, corner, out, n);
	for (i = 0; i < f->obstacle_count; i++) {
		const struct sim_obstacle *o = &f->obstacles[i];
		double dx = o->x_mm - r->cx, dy = o->y_mm - r->cy;
		double reach =
			r->bound +
			(o->shape == SIM_SHAPE_CIRCLE
				 ? o->radius_mm
				 : sqrt(o->half_x_mm * o->half_x_mm + o->half_y_mm * o->half_y_mm));

		if (dx * dx + dy * dy >= reach * reach)
			continue;
		if (o->shape == SIM_SHAPE_CIRCLE)
			n = collide_circle(o, r, out, n);
		else
			n = collide_box(o, r, corner, out, n);
	}
	return n;
}
