/* The error radius ("rayon d'erreur max") of the odometry's pose: a bound, in millimetres, that
 * the true position stays within with a configured probability. It adds a worst-case systematic
 * term (calibration residuals of the wheel ratio, the track and the wheel scale) to k times the
 * largest standard deviation of a random-walk covariance propagated as in Chong & Kleeman (ICRA
 * 1997) and Kelly (CMU-RI-TR-00-20). Model, units and limits: docs/odometry.md.
 */
#ifndef ASSERV_UNCERTAINTY_H
#define ASSERV_UNCERTAINTY_H

#include <stdint.h>

#include "feature_set.h"

#define UNCERTAINTY_RADIUS_MAX_MM 255
#define UNCERTAINTY_BATCH_TICKS_MAX 64
/* A batch also ends when its wheels have travelled this much [um], bounding the linearisation. */
#define UNCERTAINTY_BATCH_PATH_UM ((int32_t)1 << 14)
/* Largest accepted noise coefficient [mm^2/m * 2^16] (16 mm^2/m). */
#define UNCERTAINTY_NOISE_Q16_MAX ((uint32_t)1 << 20)
/* A batch's propagation and the radius refresh are spread over this many ticks after the batch
 * ends, one short stage per tick (docs/odometry.md). */
#define UNCERTAINTY_STAGES 20
/* Units of the covariance: x and y in 4 um, the heading in 2^-16 rad. */
#define UNCERTAINTY_POS_UM 4

enum uncertainty_axis { UNCERTAINTY_AXIS_X, UNCERTAINTY_AXIS_Y };

struct uncertainty_config {
	/* Variance of a wheel's travel per length travelled, k in Var = k |ds| (Chong & Kleeman)
	 * [mm^2/m * 2^16] = [um^2/um * 2^16], 0..2^20; physics.md: 0.04..0.25 mm^2/m. */
	uint32_t noise_left_mm2_per_m_q16;
	uint32_t noise_right_mm2_per_m_q16;
	uint16_t k_q8; /* radius / sigma [2^-8], 1..65535: 627 = 2.45 (95 %), 776 = 3.03 (99 %) */
	uint16_t
		batch_ms; /* covariance update this often, 1..UNCERTAINTY_BATCH_TICKS_MAX updates */
};

/* The odometry's model in effect and how far it may be off: state, not configuration, since a
 * calibration replaces it (uncertainty_set_model()). */
struct uncertainty_model {
	uint32_t track_um;        /* encoder track, as in odometry [um], 2^14..2^21 */
	uint32_t ratio_error_ppm; /* bound on the right/left wheel factor ratio error [1e-6], <= 1e6
				   */
	uint32_t track_error_um;  /* bound on the track error [um], <= track_um */
	uint32_t scale_error_ppm; /* bound on the common wheel factor error [1e-6], <= 1e6 */
};

/* A batch of wheel travels [um * 2^8] (8.4 m before they could overflow): signed sums, and
 * absolute sums for the noise. */
struct uncertainty_batch {
	int32_t left_q8, right_q8;
	uint32_t abs_left_q8, abs_right_q8;
	uint32_t heading_turn32; /* at its end */
	uint8_t ticks;
};

#if CONFIG_FIX
/* A position fix being fused (uncertainty_fuse_begin()): the covariance at the fix's time
 * [the covariance's units] with the coordinates fused so far, the innovations left, the
 * state's correction so far [4 um, 2^-16 rad], the fix's variances (position, heading), the
 * growth since the fix's time as a sigma [4 um], the squared Mahalanobis distance so far [2^-8],
 * and what the fix carries on to the last step. */
struct uncertainty_fusion {
	int64_t p[3][3];
	int64_t nu[3];
	int64_t delta[3];
	int64_t r[2];
	int64_t g;
	uint64_t d2;
	int32_t since_dx_um, since_dy_um;
	uint32_t gate_q8;
	uint8_t heading;      /* the fix has a heading */
	uint8_t saturated;    /* the prior's, its systematic terms folded in */
	uint8_t stage_before; /* the radius's stage the fusion held: back to it after an outlier */
};
#endif

struct uncertainty {
	struct uncertainty_config cfg;
	struct uncertainty_model model;
	uint16_t rate_hz; /* uncertainty_update() calls per second */
	/* Derived from cfg, model and rate_hz. */
	uint8_t batch_ticks;  /* batch_ms in updates */
	uint16_t turn_per_um; /* heading per um of right - left travel [turn * 2^32 / um * 2^-16] */
	uint16_t inv_track_q28;  /* 2^28 / track */
	uint16_t g_q12;          /* 2^30 / track: heading [2^-16 rad] per 4 um of right - left */
	uint32_t ratio_coef_q32; /* systematic radius [um] per 2^14 um^2 of w1, w2, per um of d */
	uint32_t track_coef_q32;
	uint32_t scale_coef_q32;

	/* Covariance of (x, y) [4 um] and heading [2^-16 rad]: xx, xy, yy [(4 um)^2], xt, yt
	 * [4 um * 2^-16 rad], tt [(2^-16 rad)^2]. Capped at xx, yy <= 2^30 (sigma 131 mm) and
	 * tt <= 2^28 (sigma 0.25 rad): past them the radius reads 255 until a reset. */
	int32_t xx, xy, yy, xt, yt, tt;
	uint8_t saturated;

	/* Systematic part: twice the signed travel of the midpoint [um] and the right - left travel
	 * [um] since the last heading reset, and the first-order position error per unit parameter
	 * error: w1 (wheel ratio) and w2 (track) [um^2 / 4] as exact 48-bit sums (hi 2^16 + lo,
	 * saturating), d (scale) [um]. */
	int32_t travel2_um;
	int32_t turn_um;
	struct uncertainty_sum48 {
		int32_t hi;
		uint16_t lo;
	} w1[2], w2[2];
	int32_t d[2];
	/* Position errors that no longer cancel [um], per coordinate (a box): the systematic terms
	 * of bounds that were replaced (uncertainty_set_model()), added to the radius. */
	uint32_t fixed_um[2];

	struct uncertainty_batch acc; /* accumulating */
	struct uncertainty_batch run; /* being propagated */
	uint8_t stage;                /* of run: 0 idle, 1..UNCERTAINTY_STAGES */
	/* Between stages: twice the midpoint travel and right - left travel [um], the direction
	 * [2^-14] and displacement [um] of the batch, its noise (right + left, right - left)
	 * [(4 um)^2], Fp's DY tt, Fd's U, V [2^-15], the eigenvalue's length, the radius [um]. */
	int32_t s2_um, diff_um;
	int16_t c_q14, s_q14;
	int32_t dx_um, dy_um;
	int32_t qp, qm;
	int32_t my;
	int16_t u_q15, v_q15;
	uint32_t h;
	uint32_t radius_um;

	uint8_t radius_mm;
#if CONFIG_FIX
	struct uncertainty_fusion
		fusion; /* a position fix's, in flight (stage past the radius's) */
#endif
};

/* Check cfg and model and start from a zero radius (call uncertainty_reset for another start),
 * updated rate_hz times a second. Returns 0, or -EDOM if cfg or model is out of range (u is then
 * unusable). interrupt-safe: no. */
int uncertainty_init(struct uncertainty *u, const struct uncertainty_config *cfg, uint16_t rate_hz,
		     const struct uncertainty_model *model);

/* Change the model keeping the accumulated uncertainty. What the old residual bounds
 * accumulated is kept as it is: the systematic position terms become fixed errors (they no
 * longer cancel on the way back) and the systematic heading drift joins the heading variance;
 * the new bounds apply from here on. Returns 0, or -EDOM (the old model is kept).
 * interrupt-safe: no (between two ticks). */
int uncertainty_set_model(struct uncertainty *u, const struct uncertainty_model *model);

/* One update: the wheel travels since the last one (odometry_travel_q16() of their counts
 * [um * 2^16]) and the heading after the tick [turn * 2^32]. Accumulates; a batch ends
 * every batch_ticks ticks, or after UNCERTAINTY_BATCH_PATH_UM of travel, and is propagated over
 * the next UNCERTAINTY_STAGES ticks, one stage per call, the last refreshing the radius. A batch
 * that is due while the previous one is still being propagated goes on accumulating until the
 * stages are done, or until a wheel's travel in it would pass 32.7 mm, where the stages in flight
 * are finished at once (at 1 kHz, only above 1.5 m/s). Under 2 000 cycles on an AVR, except
 * then. interrupt-safe: no (tick only). */
void uncertainty_update(struct uncertainty *u, int32_t left_q16, int32_t right_q16,
			uint32_t heading_turn32);

/* Up to n more stages of the batch in flight, if there is one: a caller that runs
 * uncertainty_update() less often (the board's slow steps every 2^k ticks, with n = 2^k - 1)
 * keeps the propagation as fast in time, so that a batch is never finished at once on the way.
 * interrupt-safe: no. */
void uncertainty_advance(struct uncertainty *u, uint8_t n);

/* The error radius [mm], rounded up, 0..255 (255 also means "255 or more").
 * interrupt-safe: yes (one byte). */
uint8_t uncertainty_get_radius_mm(const struct uncertainty *u);

/* Full recalibration: position known within radius_um, heading within heading_turn32 (both
 * bounds at the configured probability; sigma = bound / k), systematic terms cleared, the batches
 * in progress dropped. The radius then reads ceil(radius_um / 1000).
 * interrupt-safe: no (between two ticks). */
void uncertainty_reset(struct uncertainty *u, uint32_t radius_um, uint32_t heading_turn32);

/* One coordinate known again (e.g. after a border contact): its variance is set from bound_um,
 * its correlations and its systematic errors cleared; the other coordinate keeps its
 * (conservative) variance. The radius follows within UNCERTAINTY_STAGES ticks.
 * interrupt-safe: no (between two ticks). */
void uncertainty_reset_axis(struct uncertainty *u, enum uncertainty_axis axis, uint32_t bound_um);

/* The heading known again within bound_turn32 (e.g. after aligning on a border): its variance is
 * set, its correlations cleared, and the systematic heading drift restarts from zero; position
 * errors already accumulated are kept. The radius follows within UNCERTAINTY_STAGES ticks.
 * interrupt-safe: no (between two ticks). */
void uncertainty_reset_heading(struct uncertainty *u, uint32_t bound_turn32);

/* The position component along a direction known again within bound_um (e.g. across a field
 * line, or along the approach to a basket): the covariance is turned into (along, lateral)
 * coordinates, the along variance set from bound_um and its correlations dropped, the lateral
 * variance and its correlation with the heading kept; the systematic terms keep only their
 * lateral part. direction_turn32 is the direction's angle [turn * 2^32]; the sign does not
 * matter. interrupt-safe: no (between two ticks). */
void uncertainty_reset_along(struct uncertainty *u, uint32_t direction_turn32, uint32_t bound_um);

/* The robot may have moved in ways the odometry did not see: its position by up to position_um
 * (slid sideways in a collision, which the free wheels do not measure), and one wheel by up to
 * wheel_um (an encoder wire cut, a wheel lifted), which moves the position by wheel_um / 2 and
 * the heading by wheel_um / track. Each is added to its bound (sigma + bound / k). The radius
 * follows within UNCERTAINTY_STAGES ticks. interrupt-safe: no (between two ticks). */
void uncertainty_widen(struct uncertainty *u, uint32_t position_um, uint32_t wheel_um);

/* The heading's bound at the configured probability [turn * 2^32], rounded up, saturating at
 * 2^31 (half a turn): how well the heading is known, to decide whether a measurement improves
 * it. interrupt-safe: no. */
uint32_t uncertainty_get_heading_bound_turn32(const struct uncertainty *u);

/* The position component along a direction known to lie within bound_um (e.g. across a basket
 * approach, the switch's window): as uncertainty_reset_along(), but only when its variance is
 * larger than the bound's. Returns 1 when it was capped, 0 when left as it was.
 * interrupt-safe: no (between two ticks). */
int uncertainty_cap_along(struct uncertainty *u, uint32_t direction_turn32, uint32_t bound_um);

/* What a reset keeps of the covariance to resume from (keep.h): the heading's variance and the
 * systematic heading drift's integrals. Interrupt-safe: no. */
struct uncertainty_kept {
	int32_t tt;
	int32_t travel2_um;
	int32_t turn_um;
};
void uncertainty_keep(const struct uncertainty *u, struct uncertainty_kept *k);

/* Resume after a reset from a radius [um] and what uncertainty_keep() kept: each coordinate a
 * sigma of radius / k, uncorrelated (conservative: the radius bounds the systematic part too),
 * the heading's variance with its systematic drift folded in (under the model in effect, the
 * uncalibrated one at a restart: its bounds are the wider), then widened as uncertainty_widen()
 * by what the robot may have travelled unseen; the radius refreshed at once. Interrupt-safe: no. */
void uncertainty_resume(struct uncertainty *u, uint32_t radius_um, const struct uncertainty_kept *k,
			uint32_t position_um, uint32_t wheel_um);

/* A position fix against the estimate at the time it was measured (uncertainty_fuse_begin()). */
struct uncertainty_fix {
	int32_t dx_um, dy_um;    /* fix - estimate [um] */
	int32_t dheading_turn32; /* fix - estimate, wrapped [turn * 2^32] */
	uint32_t sigma_um;       /* standard deviation of x and of y [um] */
	uint32_t sigma_turn32;   /* of the heading [turn * 2^32]; 0: the fix has no heading */
	uint32_t growth_um;      /* how much the radius grew since it was measured [um] */
	uint32_t gate_q8;        /* largest squared Mahalanobis distance accepted [2^-8]; 0: any */
	int32_t since_dx_um;     /* the estimate's travel from the measured time to now [um] */
	int32_t since_dy_um;
};

/* What a fix moved the estimate by, at the time it was measured. */
struct uncertainty_correction {
	int32_t dx_um, dy_um;
	int32_t dheading_turn32;
	uint32_t d2_q8; /* the fix's squared Mahalanobis distance to the estimate [2^-8] */
};

/* Fuse a position fix with the covariance (a Kalman update, one coordinate at a time: the fix's
 * noise is diagonal), at the time the fix was measured: the covariance is carried back there
 * along the travel since (a heading error then moves the position now by the travel turned a
 * quarter), fused, and carried forward again. The systematic terms are folded in first, each bound
 * as a sigma of bound / k, so that the radius that follows is k sigma of the fused covariance. The
 * growth of the radius since the fix was measured is added back afterwards as a variance (sigma =
 * growth / k): the fix says nothing of what the odometry did since, and the fixes in flight each
 * add theirs. A saturated covariance takes any fix. In 64 bits.
 *
 * Over five calls, so that no planner period pays for all of it (bench/stm32.py --fixes):
 * uncertainty_fuse_begin() folds the terms and carries the covariance back; each
 * uncertainty_fuse_step() then does one more: x, y, the heading, the end. Meanwhile the radius's
 * stages are held (a batch waits: the covariance is not touched), and whatever changes the
 * covariance (a widening, a reset, a recalibration, a new model, a batch handed over early)
 * abandons the fusion first, before anything of it was committed: the step then returns
 * UNCERTAINTY_FUSE_ABANDONED and the fix may be tried again.
 *
 * uncertainty_fuse_begin(): only when uncertainty_fuse_ready(). Returns 1 when the fix is beyond
 * any use (nothing started: an outlier), 0 when the fusion started. Interrupt-safe: no. */
#if CONFIG_FIX
int uncertainty_fuse_begin(struct uncertainty *u, const struct uncertainty_fix *f);

enum uncertainty_fuse_result {
	UNCERTAINTY_FUSE_BUSY,      /* one more step to call, the next period */
	UNCERTAINTY_FUSE_FUSED,     /* c: how far to move the estimate at the measured time */
	UNCERTAINTY_FUSE_OUTLIER,   /* the squared Mahalanobis distance passed gate_q8: nothing */
	UNCERTAINTY_FUSE_ABANDONED, /* the covariance changed under it, or none in flight */
};

/* The next step of the fusion in flight. At its end, FUSED or OUTLIER, with c->d2_q8 the fix's
 * squared Mahalanobis distance; FUSED: the radius follows within UNCERTAINTY_STAGES updates
 * (until then it reads the larger one of before). Interrupt-safe: no. */
enum uncertainty_fuse_result uncertainty_fuse_step(struct uncertainty *u,
						   struct uncertainty_correction *c);

/* The fusion in flight, if any, given up (the fix's own side dropped it). Interrupt-safe: no. */
void uncertainty_fuse_abandon(struct uncertainty *u);
#endif

/* 1 when uncertainty_fuse_begin() may run: no batch is being propagated, the radius's stages
 * have not begun (they then start again from the fused covariance, over the next ticks), and no
 * fusion is in flight. A fix waits for it (at most UNCERTAINTY_STAGES updates), so that a
 * fusion never pays for a batch. Interrupt-safe: yes. */
int uncertainty_fuse_ready(const struct uncertainty *u);

#endif
