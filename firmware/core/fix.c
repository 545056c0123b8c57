/* Position fixes: the pose history, the fusion at the measured time, the correction carried to
 * now (fix.h). */
#include "fix.h"

#include "fixmath.h"
#include "protocol_defs.h"

void fix_init(struct fix *f, uint16_t slow_hz)
{
	uint32_t spacing = ((uint32_t)slow_hz * FIX_SPACING_MS + 999u) / 1000u;

	f->now = 0;
	f->newest = 0;
	f->forget = 0;
	f->slow_hz = slow_hz;
	f->head = 0;
	f->count = 0;
	f->spacing = (uint8_t)(spacing > 255u ? 255u : spacing < 1u ? 1u : spacing);
	f->countdown = f->spacing;
	f->outliers_in_a_row = 0;
	f->first = 0;
	f->pending = 0;
	for (uint8_t i = 0; i < FIX_QUEUE; i++) {
		f->waiting[i] = (struct fix_meas){0, 0, 0, 0, 0, 0};
		f->waiting_t[i] = 0;
	}
#if CONFIG_FIX
	f->carry = (struct fix_carry){{0, 0, 0, 0}, 0, 0, 0, 0, 0, 0, 0, 0};
	f->fusing = (struct fix_meas){0, 0, 0, 0, 0, 0};
	f->fusing_t = 0;
	f->fusing_then = (struct fix_entry){0, 0, 0, 0};
	f->fusing_newer = 0;
	f->fusing_before_um = 0;
	f->in_flight = 0;
#endif
	f->info = (struct fix_info){0, 0, 0, FIX_RESULT_NONE, 0};
	for (uint8_t i = 0; i < FIX_HISTORY_N; i++)
		f->h[i] = (struct fix_entry){0, 0, 0, 0};
}

#if CONFIG_FIX

static void push(struct fix *f, const struct odometry_pose *pose, uint32_t radius_um)
{
	f->head = (uint8_t)((f->head + 1u) % FIX_HISTORY_N);
	f->h[f->head] = (struct fix_entry){pose->x_um, pose->y_um, pose->heading_turn32, radius_um};
	f->newest = f->now;
	if (f->count < FIX_HISTORY_N)
		f->count++;
	f->countdown = f->spacing;
	if (f->carry.left) /* the entries still to move are one further from the newest */
		f->carry.next++;
	if (f->in_flight) /* and those the fusion in flight will move */
		f->fusing_newer++;
}

static void carry_some(struct fix *f);

static void fuse_begin(struct fix *f, struct odometry_pose *pose, struct uncertainty *u,
		       const struct fix_meas *z, uint32_t t);
static void fuse_step(struct fix *f, struct odometry_position *pos, struct odometry_pose *pose,
		      struct uncertainty *u);

void fix_record(struct fix *f, struct odometry_position *pos, struct odometry_pose *pose,
		struct uncertainty *u, uint8_t busy)
{
	f->now++;
	if (--f->countdown == 0)
		push(f, pose, u->radius_um);
	if (f->carry.left) {
		carry_some(f);
		return; /* the next fix is compared with a history that has moved */
	}
	if (busy)
		return;
	if (f->in_flight) {
		fuse_step(f, pos, pose, u);
		return;
	}
	if (f->pending && uncertainty_fuse_ready(u)) {
		uint8_t i = f->first;

		f->first = (uint8_t)((i + 1u) % FIX_QUEUE);
		f->pending--;
		fuse_begin(f, pose, u, &f->waiting[i], f->waiting_t[i]);
	}
}

/* The j-th newest entry. */
static struct fix_entry *entry(struct fix *f, uint32_t j)
{
	return &f->h[(f->head + FIX_HISTORY_N - j) % FIX_HISTORY_N];
}

/* a + (b - a) num / den, the heading along the shorter way. */
static struct fix_entry lerp(const struct fix_entry *a, const struct fix_entry *b, int32_t num,
			     int32_t den)
{
	struct fix_entry e = *a;

	if (den == 0 || num == 0)
		return e;
	if (num == den) { /* b itself, without the divisions: the same values */
		e.x_um = b->x_um;
		e.y_um = b->y_um;
		e.heading_turn32 = b->heading_turn32;
		e.radius_um = a->radius_um < b->radius_um ? a->radius_um : b->radius_um;
		return e;
	}
	e.x_um += (int32_t)(((int64_t)b->x_um - a->x_um) * num / den);
	e.y_um += (int32_t)(((int64_t)b->y_um - a->y_um) * num / den);
	e.heading_turn32 +=
		(uint32_t)(int32_t)((int64_t)(int32_t)(b->heading_turn32 - a->heading_turn32) *
				    num / den);
	e.radius_um = a->radius_um < b->radius_um ? a->radius_um : b->radius_um;
	return e;
}

/* The estimate at period t (within the history, or between its newest entry and now), and in
 * *newer how many entries are at t or after it. Returns FIX_RESULT_NONE, or why not. */
static uint8_t pose_at(struct fix *f, uint32_t t, const struct fix_entry *now_e,
		       struct fix_entry *out, uint32_t *newer)
{
	uint32_t back, k, frac;

	*newer = 0;
	if ((int32_t)(t - f->forget) < 0)
		return FIX_RESULT_STALE;
	if (f->count == 0 || (int32_t)(t - f->newest) >= 0) {
		if (f->count == 0 && t != f->now)
			return FIX_RESULT_TOO_OLD;
		*out = f->count == 0 ? *now_e
				     : lerp(entry(f, 0), now_e, (int32_t)(t - f->newest),
					    (int32_t)(f->now - f->newest));
		return FIX_RESULT_NONE;
	}
	back = f->newest - t;
	k = back / f->spacing;
	frac = back % f->spacing;
	if (k + (frac ? 1u : 0u) >= f->count)
		return FIX_RESULT_TOO_OLD;
	*out = frac ? lerp(entry(f, k), entry(f, k + 1), (int32_t)frac, f->spacing) : *entry(f, k);
	*newer = k + 1;
	return FIX_RESULT_NONE;
}

/* q moved with the correction at the measured time: then -> then + (dx, dy), turned by dh
 * about it. */
static void carry(struct fix_entry *q, const struct fix_entry *then,
		  const struct uncertainty_correction *c, int32_t sin_q30, int32_t cos_q30)
{
	int64_t rx = (int64_t)q->x_um - then->x_um, ry = (int64_t)q->y_um - then->y_um;

	q->x_um = then->x_um + c->dx_um + (int32_t)fx_shr_round64(rx * cos_q30 - ry * sin_q30, 30);
	q->y_um = then->y_um + c->dy_um + (int32_t)fx_shr_round64(rx * sin_q30 + ry * cos_q30, 30);
	q->heading_turn32 += (uint32_t)c->dheading_turn32;
}

/* The fix against the estimate then: the innovation, the noise, the growth since. */
static void innovation(const struct fix *f, const struct fix_meas *z, const struct fix_entry *then,
		       const struct fix_entry *now_e, const struct uncertainty *u,
		       struct uncertainty_fix *uf)
{
	uf->since_dx_um = now_e->x_um - then->x_um;
	uf->since_dy_um = now_e->y_um - then->y_um;
	uf->dx_um = z->x_um - then->x_um;
	uf->dy_um = z->y_um - then->y_um;
	uf->dheading_turn32 =
		z->sigma_turn32 ? (int32_t)(z->heading_turn32 - then->heading_turn32) : 0;
	uf->sigma_um = z->sigma_um;
	uf->sigma_turn32 = z->sigma_turn32;
	uf->growth_um = u->radius_um > then->radius_um ? u->radius_um - then->radius_um : 0;
	uf->gate_q8 = f->outliers_in_a_row >= FIX_YIELD_AFTER ? 0 : FIX_GATE_Q8;
}

/* Up to FIX_CARRY_PER_PERIOD of the history entries still to move with the last fix. */
static void carry_some(struct fix *f)
{
	struct fix_carry *k = &f->carry;
	struct uncertainty_correction c = {k->dx_um, k->dy_um, k->dheading_turn32, 0};
	uint8_t n = k->left < FIX_CARRY_PER_PERIOD ? k->left : FIX_CARRY_PER_PERIOD;

	if ((uint32_t)k->next + k->left > f->count) /* the oldest ones left the history */
		k->left = k->next < f->count ? (uint8_t)(f->count - k->next) : 0;
	if (n > k->left)
		n = k->left;
	for (uint8_t j = 0; j < n; j++) {
		struct fix_entry *e = entry(f, (uint32_t)k->next + j);

		carry(e, &k->then, &c, k->sin_q30, k->cos_q30);
		e->radius_um = e->radius_um > k->shrink_um ? e->radius_um - k->shrink_um : 0;
	}
	k->next = (uint8_t)(k->next + n);
	k->left = (uint8_t)(k->left - n);
}

/* Fused: the estimate now and the history since then moved as one rigid motion (the estimate at
 * once, the history over the next periods: carry_some()), and the radius they recorded lowered
 * by what the fix took off it. */
static void correct(struct fix *f, struct odometry_position *pos, struct odometry_pose *pose,
		    const struct fix_entry *then, const struct uncertainty_correction *c,
		    uint32_t newer, uint32_t shrink_um)
{
	int32_t s, co;
	struct fix_entry now_e = {pose->x_um, pose->y_um, pose->heading_turn32, 0};

	fx_sincos((uint32_t)c->dheading_turn32, &s, &co);
	f->carry = (struct fix_carry){*then, c->dx_um,  c->dy_um, c->dheading_turn32, s,
				      co,    shrink_um, 0,        (uint8_t)newer};
	carry(&now_e, then, c, s, co);
	odometry_set_position(pos, now_e.x_um, now_e.y_um);
	pose->x_um = now_e.x_um;
	pose->y_um = now_e.y_um;
	pose->heading_turn32 = now_e.heading_turn32;
}

static uint8_t count(struct fix *f, uint8_t result, uint32_t d2_q8)
{
	f->info.last = result;
	f->info.last_d2 = (uint8_t)(d2_q8 >= (255u << 8) ? 255u : (d2_q8 + 128u) >> 8);
	if (result == FIX_RESULT_FUSED)
		f->info.fused++;
	else if (result == FIX_RESULT_OUTLIER)
		f->info.outliers++;
	else
		f->info.too_old++;
	f->outliers_in_a_row =
		result == FIX_RESULT_OUTLIER ? (uint8_t)(f->outliers_in_a_row + 1u) : (uint8_t)0;
	return result;
}

uint8_t fix_apply(struct fix *f, struct odometry_position *pos, struct odometry_pose *pose,
		  struct uncertainty *u, const struct fix_meas *z)
{
	uint32_t age = ((uint32_t)z->age_ms * f->slow_hz + 500u) / 1000u;
	uint8_t i;

	(void)pos;
	(void)pose;
	(void)u;
	if (f->pending == FIX_QUEUE) { /* the oldest waited too long */
		f->first = (uint8_t)((f->first + 1u) % FIX_QUEUE);
		f->pending--;
		(void)count(f, FIX_RESULT_TOO_OLD, 0);
	}
	i = (uint8_t)((f->first + f->pending) % FIX_QUEUE);
	f->waiting[i] = *z;
	f->waiting_t[i] = f->now - age;
	f->pending++;
	return FIX_RESULT_NONE;
}

/* A fix against the estimate at its time t: counted at once when there is none to compare it
 * with, or when it is beyond any use; else its fusion starts (fuse_step() over the next
 * periods). */
static void fuse_begin(struct fix *f, struct odometry_pose *pose, struct uncertainty *u,
		       const struct fix_meas *z, uint32_t t)
{
	struct fix_entry now_e = {pose->x_um, pose->y_um, pose->heading_turn32, u->radius_um};
	struct uncertainty_fix uf;
	uint32_t newer;
	uint8_t why = pose_at(f, t, &now_e, &f->fusing_then, &newer);

	if (why != FIX_RESULT_NONE) {
		(void)count(f, why, 0);
		return;
	}
	innovation(f, z, &f->fusing_then, &now_e, u, &uf);
	if (uf.gate_q8 == 0) /* the estimate is what is off: widened to reach the fix */
		uncertainty_widen(u, fx_mag32(uf.dx_um) + fx_mag32(uf.dy_um), 0);
	f->fusing_before_um = u->radius_um;
	if (uncertainty_fuse_begin(u, &uf)) {
		(void)count(f, FIX_RESULT_OUTLIER, UINT32_MAX);
		return;
	}
	f->fusing = *z;
	f->fusing_t = t;
	f->fusing_newer = newer;
	f->in_flight = 1;
}

/* The next step of the fusion in flight; at its end, the estimate corrected, or the outlier
 * counted. A fusion the radius abandoned (a widening, a recalibration: the covariance changed
 * under it) leaves its fix to be tried again, first in the queue. */
static void fuse_step(struct fix *f, struct odometry_position *pos, struct odometry_pose *pose,
		      struct uncertainty *u)
{
	struct uncertainty_correction c;
	uint32_t before = f->fusing_before_um;

	switch (uncertainty_fuse_step(u, &c)) {
	case UNCERTAINTY_FUSE_BUSY:
		return;
	case UNCERTAINTY_FUSE_FUSED:
		f->in_flight = 0;
		correct(f, pos, pose, &f->fusing_then, &c, f->fusing_newer,
			before > u->radius_um ? before - u->radius_um : 0);
		(void)count(f, FIX_RESULT_FUSED, c.d2_q8);
		return;
	case UNCERTAINTY_FUSE_OUTLIER:
		f->in_flight = 0;
		(void)count(f, FIX_RESULT_OUTLIER, c.d2_q8);
		return;
	default:
		f->in_flight = 0;
		if (f->pending == FIX_QUEUE) { /* no room left: it waited too long */
			(void)count(f, FIX_RESULT_TOO_OLD, 0);
			return;
		}
		f->first = (uint8_t)((f->first + FIX_QUEUE - 1u) % FIX_QUEUE);
		f->waiting[f->first] = f->fusing;
		f->waiting_t[f->first] = f->fusing_t;
		f->pending++;
		return;
	}
}

void fix_forget(struct fix *f, const struct odometry_pose *pose, struct uncertainty *u)
{
	for (; f->pending; f->pending--) /* measured before what set the pose: would undo it */
		(void)count(f, FIX_RESULT_STALE, 0);
	if (f->in_flight) {
		f->in_flight = 0;
		uncertainty_fuse_abandon(u);
		(void)count(f, FIX_RESULT_STALE, 0);
	}
	f->forget = f->now;
	f->count = 0;
	f->carry.left = 0; /* what it would move is forgotten */
	push(f, pose, u->radius_um);
}

#else

void fix_forget(struct fix *f, const struct odometry_pose *pose, struct uncertainty *u)
{
	(void)f;
	(void)pose;
	(void)u;
}

uint8_t fix_apply(struct fix *f, struct odometry_position *pos, struct odometry_pose *pose,
		  struct uncertainty *u, const struct fix_meas *z)
{
	(void)f;
	(void)pos;
	(void)pose;
	(void)u;
	(void)z;
	return FIX_RESULT_NONE; /* never reached: the protocol layer rejects SET_FIX */
}

#endif
