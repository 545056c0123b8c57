/* Geometry of the field for the simulator (internal): distances to borders and obstacles,
 * contacts of the robot outline, lines under a point. All in mm, field frame. */
#ifndef ASSERV_SIM_FIELD_H
#define ASSERV_SIM_FIELD_H

#include <stdbool.h>

#include "sim.h"

#define FIELD_BORDERS 1u
#define FIELD_BASKETS 2u
#define FIELD_OTHERS 4u
#define FIELD_ALL (FIELD_BORDERS | FIELD_BASKETS | FIELD_OTHERS)

/* The robot outline placed on the field: a rectangle. */
struct field_rect {
	double cx, cy;   /* centre [mm] */
	double ux, uy;   /* unit vector of the robot's x axis */
	double half_len; /* along u [mm] */
	double half_wid; /* across u [mm] */
	double bound;    /* radius of the circle around the centre that holds the rectangle */
};

/* One point where the outline is pressed into something. */
struct field_contact {
	double px, py; /* point of the robot that is pushed [mm] */
	double nx, ny; /* unit normal along which the robot is pushed out */
	double depth;  /* penetration [mm], > 0 */
};

#define FIELD_MAX_CONTACTS 16

/* Signed distance [mm] from (x, y) to the nearest selected thing (FIELD_* mask): > 0 free,
 * < 0 inside a border or an obstacle. Returns a large positive value if nothing is selected. */
double field_distance(const struct sim_field *f, double x, double y, unsigned mask);

/* The bounding box of each painted line, widened by its half width [mm], for field_on_line():
 * x min, x max, y min, y max of line i at box[4 i] .. box[4 i + 3]. */
void field_line_boxes(const struct sim_field *f, double *box);

/* True if (x, y) is on a painted line; box from field_line_boxes(). *margin [mm]: how far the
 * point can move before the answer may change (0 on the edge of a line). */
bool field_on_line(const struct sim_field *f, const double *box, double x, double y,
		   double *margin);

/* Contacts of the rectangle with the borders and obstacles; returns their number
 * (0..FIELD_MAX_CONTACTS). Small penetrations are handled exactly for corners pressed into a
 * border or a box and for edges or corners on a circle; two boxes crossing with no corner inside
 * the other (a deep cross) are missed. */
int field_collide(const struct sim_field *f, const struct field_rect *r, struct field_contact *out);

#endif /* ASSERV_SIM_FIELD_H */
