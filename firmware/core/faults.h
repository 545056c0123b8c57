/* Stop conditions other than arrival: shock sensors, motor problems (following error,
 * overcurrent, slip, a free-wheel encoder suspected lost) and the unrecoverable faults (the
 * encoder confirmed lost at the next order, repeated motor problems). Every check is gated so
 * that what the robot does on purpose is not a fault: no following-error check while pushing
 * against a basket or a border, and no motor problem while no order runs (a robot pushed while
 * it holds its position, or rocking after an abandoned order): an overcurrent then only makes
 * the board let go of the position it holds (FAULTS_YIELD). docs/failure-model.md gives the
 * thresholds and detection times. */
#ifndef ASSERV_FAULTS_H
#define ASSERV_FAULTS_H

#include <stdint.h>

enum faults_event {
	FAULTS_NONE = 0,
	FAULTS_SHOCK_BORD,   /* a border-side shock sensor: CHOC_BORD */
	FAULTS_SHOCK_PANIER, /* a basket-side shock sensor: CHOC_PANIER */
	FAULTS_MOTOR,        /* PB_MOTEUR: the order is abandoned, the next one may start */
	FAULTS_GRAVE,        /* PB_GRAVE: motors off until reset */
	FAULTS_YIELD,        /* overcurrent with no order running: stop holding, no status bit */
};

/* Which check fired last (for DEBUG and tests). */
enum faults_cause {
	FAULTS_CAUSE_NONE = 0,
	FAULTS_CAUSE_FOLLOWING,
	FAULTS_CAUSE_OVERCURRENT,
	FAULTS_CAUSE_SLIP,
	FAULTS_CAUSE_ENCODER_LOST,
	FAULTS_CAUSE_REPEATED,
};

struct faults_config {
	uint8_t shock_basket_mask;       /* shock sensors on the basket side; the others: border */
	int32_t following_max_um;        /* following error that counts as blocked ... */
	uint16_t following_ms;           /* ... for this long (consecutive checks) */
	int16_t current_max_ma;          /* overcurrent ... */
	uint16_t current_ms;             /* ... for this long (consecutive checks) */
	uint8_t motor_encoders;          /* 0: no motor encoders, no slip or encoder-lost checks */
	uint32_t motor_um_per_count_q16; /* drive wheel travel per motor count [um * 2^16] */
	int32_t slip_max_um;             /* drive wheels vs free wheels disagreement ... */
	uint16_t slip_window_ms;   /* ... in leaky sums over this window (2^n checks, n floored) */
	int32_t lost_min_um;       /* a free wheel counted 0 while its motor turned this much ... */
	uint8_t repeat_max;        /* this many PB_MOTEUR (1..8) ... */
	uint16_t repeat_window_ms; /* ... within this window: PB_GRAVE */
};

/* What the checks look at this tick. */
struct faults_inputs {
	uint8_t shocks;
	int16_t current_ma[2];
	uint16_t motor_count[2];
	int32_t free_step_q16[2]; /* free wheel travel this tick [um * 2^16] */
	int32_t free_ratio_q16;   /* drive track / encoder track [2^-16] */
	int32_t dist_err_um;      /* following errors: setpoint of the last tick - measure */
	int32_t angle_err_um;
	uint8_t moving;  /* an order runs (not IDLE) */
	uint8_t pushing; /* contact expected: no following-error check */
};

struct faults {
	struct faults_config cfg;
	/* cfg's durations in checks */
	uint16_t following_ticks;
	uint16_t current_ticks;
	uint16_t repeat_window_ticks;
	uint8_t slip_shift; /* the slip window: 2^slip_shift checks */
	uint16_t last_motor[2];
	uint16_t following_count;
	uint16_t current_count;
	int32_t slip_dist_q16; /* leaky sums [um * 2^16] */
	int32_t slip_angle_q16;
	/* Since each free wheel last counted [um]: its motor's travel, and the other free
	 * wheel's travel with its sign. */
	int32_t lost_motor_um[2];
	int32_t lost_other_um[2];
	uint8_t lost_suspect;       /* bit per side: judged lost once, silent since */
	uint32_t now;               /* [ticks] since init */
	uint32_t motor_fault_at[8]; /* [ticks] of the last PB_MOTEUR events, ring */
	uint8_t n_motor_faults;     /* total, saturating */
	uint8_t shock_ignored;      /* pressed when the order started: released, they re-arm */
	uint8_t grave;
	uint8_t cause;
};

/* Checked rate_hz times a second (faults_check()). Returns 0, or -1 when the configuration is
 * out of range. motor_count gives the motor counts to start from. Interrupt-safe: no. */
int faults_init(struct faults *f, const struct faults_config *cfg, uint16_t rate_hz,
		const uint16_t motor_count[2]);

/* A new order starts: the shock sensors pressed now (the robot against the border it backs away
 * from) do not stop it until they have been released once. Interrupt-safe: no. */
void faults_order_started(struct faults *f, uint8_t shocks_now);

/* One tick of checks; returns the most serious event (enum faults_event). PB_GRAVE latches.
 * Interrupt-safe: no. */
uint8_t faults_check(struct faults *f, const struct faults_inputs *in);

#endif
