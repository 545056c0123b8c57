/* The board in closed loop with the simulator through the host port: every order, its state
 * transitions and its stop conditions, asserted on the status the master reads, the estimate
 * and the simulator's ground truth. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>
#include <math.h>

#include <cmocka.h>

#include "host.h"
#include "port.h"

static struct host h;

/* The whole suite runs twice: the slow steps at every tick, and at every 8th (board.h). */
static uint8_t slow_shift;

static void setup_field(struct sim_field *f)
{
	sim_field_defaults(f);
}

static void start(const struct sim_field *f)
{
	struct sim_config sc;
	struct board_config bc;

	sim_config_defaults(&sc);
	host_board_config(&sc, f, &bc);
	bc.slow_shift = slow_shift;
	bc.planner_ticks = slow_shift ? 1 : 0;
	assert_int_equal(host_init(&h, &bc, &sc, f), 0);
}

/* Ticks for a message to act on the servo: the next slow tick takes it, the one after hands
 * the result over (board.h); with the slow steps at every tick, the next tick. */
/* The longest wait of a message for its effect on the servo: the rest of the period, then the
 * planner's ticks (board_config.planner_ticks: 0 at one rate, the tick itself; 1 at 125 Hz, the
 * planner run by the port after the tick). */
static uint32_t latency_ticks(void)
{
	return slow_shift ? (1u << slow_shift) + 1u : 1u;
}

/* ... and for new wheel factors, installed at the end of the period after the planner's. */
static uint32_t wheels_latency_ticks(void)
{
	return 2u << slow_shift;
}

static void send(const uint8_t *bytes, uint8_t n)
{
	host_i2c_write(&h, bytes, n, 1);
}

static uint8_t status(void)
{
	uint8_t s;

	host_i2c_read(&h, &s, 1);
	return s;
}

/* Ticks until BUSY_TRAJET clears (the master's `while (BUSY_TRAJET)`), at most max. */
static uint32_t run_until_idle(uint32_t max)
{
	uint32_t n = 0;

	do {
		host_tick(&h);
		n++;
	} while ((status() & STATUS_BUSY_TRAJET) && n < max);
	return n;
}

static void truth(double *x, double *y, double *heading_deg)
{
	struct sim_truth t;

	sim_get_truth(&h.sim, &t);
	*x = t.odo_pose.x_mm;
	*y = t.odo_pose.y_mm;
	*heading_deg = t.odo_pose.heading_rad * 57.29577951308232;
}

static void position(int16_t *x, int16_t *y, int8_t *angle_2deg, uint8_t *radius)
{
	uint8_t r[6];

	send((const uint8_t[]){PROTO_POSITION}, 1);
	host_i2c_read(&h, r, 6);
	*x = (int16_t)(uint16_t)(r[0] << 8 | r[1]);
	*y = (int16_t)(uint16_t)(r[2] << 8 | r[3]);
	*angle_2deg = (int8_t)r[4];
	*radius = r[5];
}

static void goto_mm(int16_t x, int16_t y)
{
	uint8_t f[6] = {PROTO_GOTO, (uint8_t)((uint16_t)x >> 8),
			(uint8_t)x, (uint8_t)((uint16_t)y >> 8),
			(uint8_t)y, 0};

	send(f, 6);
}

/* GOTO: busy at once, TRANSLATE then SETTLE, ends DONE settled on the target:
 * estimate within 1 mm, truth within 2 mm (a perfect robot), in about the profile's time. */
static void test_goto_arrives(void **state)
{
	struct sim_field f;
	int16_t x, y;
	int8_t a;
	uint8_t r;
	double tx, ty, th;
	uint32_t ticks, saw_rotate = 0, saw_translate = 0;

	(void)state;
	setup_field(&f);
	start(&f);
	send((const uint8_t[]){PROTO_SET_VITESSE_TRAJ, 100, 100}, 3);
	send((const uint8_t[]){PROTO_SET_VITESSE_ROT, 50, 100}, 3);
	goto_mm(200, 100);
	assert_true(status() & STATUS_BUSY_TRAJET);
	for (ticks = 0; ticks < 10000; ticks++) {
		host_tick(&h);
		saw_rotate += h.board.planner.orders.state == ORDER_STATE_ROTATE;
		saw_translate += h.board.planner.orders.state == ORDER_STATE_TRANSLATE;
		if (!(status() & STATUS_BUSY_TRAJET))
			break;
	}
	/* A 3.8 degree turn is inside the heading window: the planner step that takes the order
	 * aims and starts translating at once (no tick shows ROTATE); SETTLE may end at the step
	 * that enters it. */
	assert_true(saw_rotate == 0 && saw_translate > 0);
	assert_int_equal(h.board.planner.orders.end_reason, END_REASON_DONE);
	assert_int_equal(status(), 0);
	position(&x, &y, &a, &r);
	truth(&tx, &ty, &th);
	print_message("GOTO 200,100 from -1300,0: %u ticks, estimate (%d, %d) %d*2 deg r %u, truth "
		      "(%.2f, %.2f) %.2f deg\n",
		      ticks, x, y, a, r, tx, ty, th);
	assert_int_equal(x, 200);
	assert_int_equal(y, 100);
	assert_true(fabs(tx - 200.0) < 2.0 && fabs(ty - 100.0) < 2.0);
	/* 1503 mm at 1 m/s, 1 m/s^2: 2.50 s of translation; plus a 3.8 degree turn. */
	assert_true(ticks < 3200);
}

/* A GOTO that needs a turn: ROTATE first (no translation until the heading is within the
 * window), then TRANSLATE, SETTLE; the heading ends on the bearing. */
static void test_goto_turns_first(void **state)
{
	struct sim_field f;
	uint32_t ticks, rotate_ticks = 0;
	double x0, y0, hd, tx, ty, th;

	(void)state;
	setup_field(&f);
	start(&f);
	truth(&x0, &y0, &hd);
	goto_mm(-1300, 500);
	for (ticks = 0; ticks < 20000; ticks++) {
		host_tick(&h);
		if (h.board.planner.orders.state == ORDER_STATE_ROTATE) {
			rotate_ticks++;
			truth(&tx, &ty, &th);
			assert_true(fabs(tx - x0) < 1.0 && fabs(ty - y0) < 1.0);
		}
		if (!(status() & STATUS_BUSY_TRAJET))
			break;
	}
	truth(&tx, &ty, &th);
	print_message("90 degree GOTO: %u ticks, %u rotating, truth (%.2f, %.2f) %.2f deg\n", ticks,
		      rotate_ticks, tx, ty, th);
	assert_true(rotate_ticks > 100);
	assert_true(fabs(tx + 1300.0) < 2.0 && fabs(ty - 500.0) < 2.0);
	assert_true(fabs(th - 90.0) < 1.0);
}

/* GOTO_REVERSE: straight back, heading kept. */
static void test_goto_reverse(void **state)
{
	struct sim_field f;
	double x0, y0, h0, x1, y1, h1;

	(void)state;
	setup_field(&f);
	start(&f);
	goto_mm(-1000, 0);
	run_until_idle(20000);
	truth(&x0, &y0, &h0);
	send((const uint8_t[]){PROTO_GOTO_REVERSE, 200}, 2);
	assert_true(run_until_idle(20000) < 20000);
	truth(&x1, &y1, &h1);
	assert_true(fabs((x0 - x1) - 200.0) < 1.5);
	assert_true(fabs(y1 - y0) < 1.0 && fabs(h1 - h0) < 0.2);
	assert_int_equal(h.board.planner.orders.end_reason, END_REASON_DONE);
}

/* STOP mid-move: decelerates (no hard stop), ends STOPPED, not busy. */
static void test_stop(void **state)
{
	struct sim_field f;
	double x0, y0, hd, x1, y1;

	(void)state;
	setup_field(&f);
	start(&f);
	send((const uint8_t[]){PROTO_SET_VITESSE_TRAJ, 50, 50}, 3);
	goto_mm(1000, 0);
	for (int i = 0; i < 1500; i++)
		host_tick(&h);
	truth(&x0, &y0, &hd);
	send((const uint8_t[]){PROTO_STOP}, 1);
	assert_true(status() & STATUS_BUSY_TRAJET);
	run_until_idle(5000);
	truth(&x1, &y1, &hd);
	assert_int_equal(h.board.planner.orders.end_reason, END_REASON_STOPPED);
	/* Braking from 0.5 m/s at 0.5 m/s^2 takes 250 mm. */
	assert_true(x1 - x0 > 230.0 && x1 - x0 < 270.0);
}

/* A new GOTO while moving replaces the order without a jump of the setpoints: those the servo
 * follows, every tick (between two slow ticks, interpolated). */
static void test_replace_is_smooth(void **state)
{
	struct sim_field f;
	int32_t prev_v = 0, max_dv = 0;

	(void)state;
	setup_field(&f);
	start(&f);
	send((const uint8_t[]){PROTO_SET_VITESSE_TRAJ, 80, 80}, 3);
	goto_mm(0, 0);
	for (int i = 0; i < 4000; i++) {
		int32_t v, dv;

		if (i == 1500)
			goto_mm(0, 600);
		host_tick(&h);
		v = h.board.servo.sp_dist.vel_um_s;
		dv = v > prev_v ? v - prev_v : prev_v - v;
		if (dv > max_dv)
			max_dv = dv;
		prev_v = v;
	}
	/* 0.8 m/s^2 at 1 kHz: 800 um/s per tick. */
	assert_true(max_dv <= 801);
	run_until_idle(20000);
	assert_int_equal(h.board.planner.orders.end_reason, END_REASON_DONE);
}

/* A GOTO to a point the robot is about to pass, given at full speed: it ends (no endless
 * turning near the target) and settles on the point. */
static void test_replace_near_target_at_speed(void **state)
{
	struct sim_field f;
	uint32_t ticks;
	double tx, ty, th;

	(void)state;
	setup_field(&f);
	start(&f);
	send((const uint8_t[]){PROTO_SET_VITESSE_TRAJ, 150, 150}, 3);
	goto_mm(1000, 0);
	for (ticks = 0; ticks < 20000; ticks++) {
		struct odometry_pose p = board_get_pose(&h.board);

		host_tick(&h);
		if (p.x_um > -200000)
			break;
	}
	goto_mm(-100, 20); /* 100 mm ahead, 20 mm aside at about 1.5 m/s: it turns, then passes */
	ticks = run_until_idle(20000);
	truth(&tx, &ty, &th);
	print_message("replaced at speed: %u ticks, truth (%.2f, %.2f)\n", ticks, tx, ty);
	assert_true(ticks < 20000);
	assert_int_equal(h.board.planner.orders.end_reason, END_REASON_DONE);
	/* A straight correction along the heading: on the target's abscissa. */
	assert_true(fabs(tx + 100.0) < 2.0);
}

/* A shock sensor stops the trajectory in the tick it closes (with the slow steps every 8th tick,
 * within two of their periods): CHOC_BORD, motors no longer driving forward. */
static void test_shock_stops(void **state)
{
	struct sim_field f;
	uint32_t ticks = 0;

	(void)state;
	setup_field(&f);
	start(&f);
	send((const uint8_t[]){PROTO_SET_VITESSE_TRAJ, 30, 50}, 3);
	goto_mm(1600, 0); /* beyond the border at x = 1500 */
	while (!(h.board.planner.status & STATUS_CHOC_BORD) && ticks < 20000) {
		struct sim_sensors s;

		sim_read_sensors(&h.sim, &s);
		if (s.shock_mask) {
			/* The board sees the switch at this tick: it must stop now. */
			uint32_t n = 0;

			do {
				host_tick(&h);
				ticks++;
			} while (++n < latency_ticks() &&
				 h.board.servo.last_out.duty_q15[0] >= 3000);
			assert_true(h.board.planner.status & STATUS_CHOC_BORD);
			assert_true(h.board.servo.last_out.duty_q15[0] < 3000);
			break;
		}
		host_tick(&h);
		ticks++;
	}
	assert_int_equal(status() & (STATUS_CHOC_BORD | STATUS_BUSY_TRAJET), STATUS_CHOC_BORD);
	assert_int_equal(h.board.planner.orders.end_reason, END_REASON_SHOCK);
	/* The next order clears it. */
	send((const uint8_t[]){PROTO_GOTO_REVERSE, 100}, 2);
	host_tick(&h);
	assert_int_equal(status() & STATUS_CHOC_BORD, 0);
}

/* GOTO_PANIER: turn to the angle, push until the basket switch, CHOC_PANIER, position
 * recalibrated from the basket's geometry. */
static void test_goto_panier(void **state)
{
	struct sim_field f;
	uint32_t ticks;
	double tx, ty, th;
	struct odometry_pose p;
	int saw_busy_panier = 0;

	(void)state;
	setup_field(&f);
	start(&f);
	/* The default basket at (-1200, 750), radius 125: go in front of it, then push at 90. */
	goto_mm(-1200, 300);
	run_until_idle(20000);
	send((const uint8_t[]){PROTO_GOTO_PANIER, 45}, 2);
	for (ticks = 0; ticks < 20000; ticks++) {
		host_tick(&h);
		saw_busy_panier |= (status() & STATUS_BUSY_GOTO_PANIER) != 0;
		if (!(status() & STATUS_BUSY_TRAJET))
			break;
	}
	assert_true(saw_busy_panier);
	assert_int_equal(h.board.planner.orders.end_reason, END_REASON_BASKET);
	assert_int_equal(status() & STATUS_CHOC_PANIER, STATUS_CHOC_PANIER);
	truth(&tx, &ty, &th);
	p = board_get_pose(&h.board);
	print_message("basket contact: truth (%.2f, %.2f), estimate (%.2f, %.2f)\n", tx, ty,
		      p.x_um / 1000.0, p.y_um / 1000.0);
	assert_true(fabs(p.y_um / 1000.0 - ty) < 3.0);
	assert_true(fabs(p.x_um / 1000.0 - tx) < 3.0);
}

/* GOTO_PANIER with no basket ahead: the push gives up after its maximum travel with PB_MOTEUR
 * (the basket was not reached: docs/protocol.md 4.3) and the end reason NO_BASKET, without
 * CHOC_PANIER, not counted as a motor fault, and the estimate is not recalibrated. */
static void test_goto_panier_finds_nothing(void **state)
{
	struct sim_field f;
	double tx, ty, th;

	(void)state;
	setup_field(&f);
	f.obstacle_count = 0;
	start(&f);
	send((const uint8_t[]){PROTO_GOTO_PANIER, 0}, 2);
	run_until_idle(30000);
	truth(&tx, &ty, &th);
	assert_int_equal(h.board.planner.orders.end_reason, END_REASON_NO_BASKET);
	assert_int_equal(status() & (STATUS_CHOC_PANIER | STATUS_BUSY_TRAJET | STATUS_PB_MOTEUR),
			 STATUS_PB_MOTEUR);
	assert_int_equal(h.board.planner.faults.n_motor_faults, 0);
	assert_true(fabs(tx - (-1300.0 + 500.0)) < 2.0);
}

/* A drive wheel on a slippery patch spins: PB_MOTEUR by slip (motor encoders vs free wheels). */
static void test_slip_is_a_motor_problem(void **state)
{
	struct sim_field f;

	(void)state;
	setup_field(&f);
	start(&f);
	send((const uint8_t[]){PROTO_SET_VITESSE_TRAJ, 100, 200}, 3);
	sim_set_friction_scale(&h.sim, SIM_LEFT, 0.05);
	goto_mm(0, 0);
	run_until_idle(20000);
	assert_int_equal(status() & STATUS_PB_MOTEUR, STATUS_PB_MOTEUR);
	assert_int_equal(h.board.planner.faults.cause, FAULTS_CAUSE_SLIP);
}

/* A stalled motor: the order is abandoned with PB_MOTEUR; the next order may run. */
static void test_stuck_motor(void **state)
{
	struct sim_field f;

	(void)state;
	setup_field(&f);
	start(&f);
	goto_mm(-800, 0);
	for (int i = 0; i < 300; i++)
		host_tick(&h);
	sim_set_motor_stuck(&h.sim, SIM_LEFT, true);
	run_until_idle(5000);
	assert_int_equal(status() & (STATUS_PB_MOTEUR | STATUS_BUSY_TRAJET), STATUS_PB_MOTEUR);
	assert_int_equal(h.board.planner.orders.end_reason, END_REASON_MOTOR);
	sim_set_motor_stuck(&h.sim, SIM_LEFT, false);
	goto_mm(-800, 0);
	host_tick(&h);
	assert_int_equal(status() & STATUS_PB_MOTEUR, 0);
	run_until_idle(20000);
	assert_int_equal(h.board.planner.orders.end_reason, END_REASON_DONE);
}

/* A cut free-wheel encoder while driving: the order is abandoned on suspicion (PB_MOTEUR,
 * cause ENCODER_LOST, motors off); the wheel never counts again, so the next order is PB_GRAVE:
 * motors off, orders refused. */
static void test_encoder_cut_is_grave(void **state)
{
	struct sim_field f;
	uint8_t r[3];

	(void)state;
	setup_field(&f);
	start(&f);
	goto_mm(-300, 0);
	for (int i = 0; i < 500; i++)
		host_tick(&h);
	sim_set_encoder_cut(&h.sim, SIM_RIGHT, true);
	run_until_idle(5000);
	assert_int_equal(status(), STATUS_PB_MOTEUR);
	assert_int_equal(h.board.planner.faults.cause, FAULTS_CAUSE_ENCODER_LOST);
	assert_int_equal(h.board.servo.last_out.duty_q15[0], 0);
	assert_int_equal(h.board.servo.last_out.duty_q15[1], 0);
	goto_mm(-300, 0);
	run_until_idle(5000);
	print_message("fault cause %u\n", h.board.planner.faults.cause);
	assert_true(status() & STATUS_PB_GRAVE);
	assert_int_equal(h.board.planner.faults.cause, FAULTS_CAUSE_ENCODER_LOST);
	assert_int_equal(h.board.servo.last_out.duty_q15[0], 0);
	assert_int_equal(h.board.servo.last_out.duty_q15[1], 0);
	goto_mm(0, 0);
	assert_true(status() & STATUS_COMMANDE_REJETEE);
	send((const uint8_t[]){PROTO_LAST_REJECT}, 1);
	host_i2c_read(&h, r, 3);
	assert_int_equal(r[0], REJECT_REFUSED_PB_GRAVE);
}

/* DEBUG's end reason, as the master reads it. */
static uint8_t debug_end_reason(void)
{
	uint8_t r[PROTO_DEBUG_REPLY_LEN];

	send((const uint8_t[]){PROTO_DEBUG}, 1);
	host_i2c_read(&h, r, sizeof(r));
	return r[21];
}

/* Ticks with no transaction on the bus: the master is silent. */
static void silence(uint32_t ticks)
{
	for (uint32_t i = 0; i < ticks; i++)
		host_tick(&h);
}

/* Off at power-on: a master that gives a GOTO and never polls gets it done. */
static void test_timeout_off_by_default(void **state)
{
	struct sim_field f;

	(void)state;
	setup_field(&f);
	start(&f);
	send((const uint8_t[]){PROTO_SET_VITESSE_TRAJ, 100, 100}, 3);
	goto_mm(-300, 0);
	silence(5000);
	assert_int_equal(status(), 0);
	assert_int_equal(debug_end_reason(), END_REASON_DONE);
}

/* SET_TIMEOUT 200 ms: polled every 100 ms the GOTO runs; then silence, and the tick that
 * follows 200 ms without a transaction stops the order at the current limits, as by STOP (1
 * m/s braked at 1 m/s^2: 0.5 m); DEBUG tells why. */
static void test_timeout_stops_a_silent_master(void **state)
{
	struct sim_field f;
	struct odometry_pose p0, p1;
	uint32_t n = 0;

	(void)state;
	setup_field(&f);
	start(&f);
	send((const uint8_t[]){PROTO_SET_VITESSE_TRAJ, 100, 100}, 3);
	send((const uint8_t[]){PROTO_SET_TIMEOUT, 0, 200}, 3);
	goto_mm(1000, 0);
	for (int i = 0; i < 12; i++) {
		silence(100);
		/* the last write: 1.2 s after the GOTO, at 1 m/s */
		send((const uint8_t[]){PROTO_HEARTBEAT}, 1);
	}
	do {
		host_tick(&h);
		n++;
	} while (h.board.planner.orders.state == ORDER_STATE_TRANSLATE && n < 1000);
	/* The first tick sees the heartbeat; 200 more see none. */
	assert_int_equal(n, 201);
	assert_int_equal(h.board.planner.orders.state, ORDER_STATE_STOPPING);
	p0 = board_get_pose(&h.board);
	silence(2000);
	p1 = board_get_pose(&h.board);
	print_message("timeout: stopped %d mm after the timeout\n", (p1.x_um - p0.x_um) / 1000);
	assert_true(p1.x_um - p0.x_um > 480000 && p1.x_um - p0.x_um < 520000);
	/* not busy, and not finished: abandoned; the motors off once at rest, until an order */
	assert_int_equal(status(), STATUS_PB_MOTEUR);
	assert_int_equal(debug_end_reason(), END_REASON_TIMEOUT);
	assert_int_equal(h.board.mailbox.down[h.board.mailbox.down_index].motors_off, 1);
	goto_mm(1000, 0);                                         /* and carries on */
	assert_int_equal(debug_end_reason(), END_REASON_TIMEOUT); /* not taken yet */
	send((const uint8_t[]){PROTO_SET_TIMEOUT, 0, 0}, 3);      /* run_until_idle() only polls */
	run_until_idle(10000);
	assert_int_equal(debug_end_reason(), END_REASON_DONE);
}

/* Writes keep it alive, a HEARTBEAT as much as an order; 0 turns it off. */
static void test_timeout_writes_keep_it_going(void **state)
{
	struct sim_field f;
	uint8_t s = STATUS_BUSY_TRAJET;

	(void)state;
	setup_field(&f);
	start(&f);
	send((const uint8_t[]){PROTO_SET_VITESSE_TRAJ, 100, 100}, 3);
	send((const uint8_t[]){PROTO_SET_TIMEOUT, 0, 50}, 3);
	goto_mm(-300, 0);
	for (int i = 0; i < 200 && (s & STATUS_BUSY_TRAJET); i++) {
		silence(45);
		send((const uint8_t[]){PROTO_HEARTBEAT}, 1);
		s = status();
	}
	assert_int_equal(s, 0);
	assert_int_equal(debug_end_reason(), END_REASON_DONE);
	send((const uint8_t[]){PROTO_SET_TIMEOUT, 0, 0}, 3);
	/* Straight behind: a heading error of exactly half a turn (fx_angle_dist). */
	goto_mm(-1000, 0);
	silence(5000);
	assert_int_equal(debug_end_reason(), END_REASON_DONE);
}

/* A master whose polling thread lives on while its order thread hangs: polls every 10 ms, no
 * write after the GOTO. The reads do not feed the timeout: the order stops and ends abandoned
 * (PB_MOTEUR), never read as done. */
static void test_timeout_polls_do_not_feed_it(void **state)
{
	struct sim_field f;
	uint8_t s = STATUS_BUSY_TRAJET;
	int i;

	(void)state;
	setup_field(&f);
	start(&f);
	send((const uint8_t[]){PROTO_SET_VITESSE_TRAJ, 100, 100}, 3);
	send((const uint8_t[]){PROTO_SET_TIMEOUT, 0, 200}, 3);
	goto_mm(1500, 0);
	for (i = 0; i < 1000 && (s & STATUS_BUSY_TRAJET); i++) {
		silence(10);
		s = status();
		(void)debug_end_reason(); /* a viewer's DEBUG reads too */
	}
	assert_int_equal(s, STATUS_PB_MOTEUR);
	assert_int_equal(debug_end_reason(), END_REASON_TIMEOUT);
	/* stopped well short of 1500 mm: braking from the timeout at 1.2 s, not the target */
	assert_true(board_get_pose(&h.board).x_um < 1000000);
	goto_mm(1500, 0); /* the next order clears it and runs */
	assert_int_equal(status() & STATUS_PB_MOTEUR, 0);
}

/* GOTO_PANIER +90 (180 degrees) from heading 0: a heading error of exactly half a turn, whose
 * magnitude is 2^31 (was the negation of INT32_MIN, undefined: found by fuzzing). The robot
 * turns and reaches the heading. */
static void test_half_turn(void **state)
{
	struct sim_field f;
	int16_t x, y;
	int8_t a;
	uint8_t r;

	(void)state;
	setup_field(&f);
	f.obstacle_count = 0; /* no basket: the push ends by itself */
	start(&f);
	send((const uint8_t[]){PROTO_GOTO_PANIER, 90}, 2);
	for (int i = 0; i < 3000; i++)
		host_tick(&h);
	position(&x, &y, &a, &r);
	assert_true(a == 90 || a == -90);
}

/* SET_NEW_POS moves the estimate by minus the error, between two ticks, and the robot does not
 * move for it. */
static void test_set_new_pos(void **state)
{
	struct sim_field f;
	int16_t x, y;
	int8_t a;
	uint8_t r;
	double tx0, ty0, th0, tx1, ty1, th1;

	(void)state;
	setup_field(&f);
	start(&f);
	host_tick(&h);
	truth(&tx0, &ty0, &th0);
	/* err x +5 mm, y -3 mm, angle +10 degrees */
	send((const uint8_t[]){PROTO_SET_NEW_POS, 0, 5, 0xFF, 0xFD, 0, 10}, 7);
	for (int i = 0; i < 500; i++)
		host_tick(&h);
	position(&x, &y, &a, &r);
	truth(&tx1, &ty1, &th1);
	assert_int_equal(x, -1305);
	assert_int_equal(y, 3);
	assert_int_equal(a, -5);
	assert_true(fabs(tx1 - tx0) < 0.2 && fabs(ty1 - ty0) < 0.2 && fabs(th1 - th0) < 0.05);
}

/* SET_FIX's heading is signed: fixes at +20 and at -20 degrees, at the estimate's x and y, from a
 * robot at heading 0, are as far from the estimate as each other (FIX_INFO's last_d2), and far
 * enough to count. Under the sanitizers (ctest), a negative heading that the conversion treated
 * as undefined (a left shift) stops the test. */
static uint8_t fix_d2(int16_t cdeg)
{
	struct sim_field f;
	int16_t x, y;
	int8_t a;
	uint8_t r, info[7];

	setup_field(&f);
	start(&f);
	for (int i = 0; i < 100; i++) /* a history to fuse the fix in */
		host_tick(&h);
	position(&x, &y, &a, &r);
	assert_int_equal(a, 0);
	send((const uint8_t[]){PROTO_SET_FIX, (uint8_t)((uint16_t)x >> 8), (uint8_t)x,
			       (uint8_t)((uint16_t)y >> 8), (uint8_t)y,
			       (uint8_t)((uint16_t)cdeg >> 8), (uint8_t)cdeg, 20, 50, 0, 0},
	     11);
	for (uint32_t i = 0; i < 50; i++) /* queued, then fused in the next planner periods */
		host_tick(&h);
	send((const uint8_t[]){PROTO_FIX_INFO}, 1);
	host_i2c_read(&h, info, 7);
	assert_int_equal(info[0] << 8 | info[1], 1); /* fused */
	return info[6];
}

static void test_set_fix_heading_sign(void **state)
{
	uint8_t plus, minus;

	(void)state;
	plus = fix_d2(2000);
	minus = fix_d2(-2000);
	assert_int_equal(plus, minus);
	assert_true(plus > 0);
}

/* SET_ODOMETRIE: absolute factors from the nominal ones, applied at the next tick, the pose and
 * the axes kept; the error radius takes the new track. Nominal: 2 pi 25 mm / 2000 counts =
 * 78.540 um, 5147185 [um/count * 2^16]; scale -1000 ppm: 5142038; then ratio +2000 ppm: left
 * * 0.999 = 5136896, right * 1.001 = 5147180. */
static void test_set_odometrie(void **state)
{
	struct sim_field f;
	struct odometry_pose p0, p1;
	int32_t d0;

	(void)state;
	setup_field(&f);
	start(&f);
	host_tick(&h);
	assert_int_equal(h.board.servo.counter.cfg.left_um_per_count_q16, 5147185);
	p0 = board_get_pose(&h.board);
	d0 = odometry_get_distance_um(&h.board.servo.counter);
	/* ratio +2000 ppm, track 280.12 mm, scale -1000 ppm */
	send((const uint8_t[]){PROTO_SET_ODOMETRIE, 0x07, 0xD0, 0x6D, 0x6C, 0xFC, 0x18}, 7);
	assert_int_equal(h.board.servo.counter.cfg.track_um, 280000); /* not before the tick */
	for (uint32_t i = 0; i < wheels_latency_ticks(); i++)
		host_tick(&h);
	assert_int_equal(h.board.servo.counter.cfg.left_um_per_count_q16, 5136896);
	assert_int_equal(h.board.servo.counter.cfg.right_um_per_count_q16, 5147180);
	assert_int_equal(h.board.servo.counter.cfg.track_um, 280120);
	assert_int_equal(h.board.planner.uncertainty.model.track_um, 280120);
	p1 = board_get_pose(&h.board);
	assert_int_equal(p1.x_um, p0.x_um);
	assert_int_equal(p1.y_um, p0.y_um);
	assert_int_equal(p1.heading_turn32, p0.heading_turn32);
	assert_int_equal(odometry_get_distance_um(&h.board.servo.counter), d0);
	assert_int_equal(status() & STATUS_COMMANDE_REJETEE, 0);
	/* Absolute, not cumulative: the nominal values again. */
	send((const uint8_t[]){PROTO_SET_ODOMETRIE, 0, 0, 0x6D, 0x60, 0, 0}, 7);
	for (uint32_t i = 0; i < wheels_latency_ticks(); i++)
		host_tick(&h);
	assert_int_equal(h.board.servo.counter.cfg.left_um_per_count_q16, 5147185);
	assert_int_equal(h.board.servo.counter.cfg.right_um_per_count_q16, 5147185);
	assert_int_equal(h.board.servo.counter.cfg.track_um, 280000);
}

/* SET_ODOMETRIE on the move, 3 % larger wheels: the travel up to the tick that installs them
 * is worth the old factors, the travel after it the new ones, in the position as on the
 * distance axis (which counts every tick with the factors of that tick). Going straight along
 * x, the two move together to the micrometre at every period's end. */
static void test_set_odometrie_moving(void **state)
{
	struct sim_field f;
	int32_t x0, d0, x1 = 0, d1 = 0;

	(void)state;
	setup_field(&f);
	start(&f);
	host_tick(&h);
	x0 = board_get_pose(&h.board).x_um;
	d0 = h.board.planner.m.dist_um;
	goto_mm((int16_t)(x0 / 1000 + 1500), (int16_t)(board_get_pose(&h.board).y_um / 1000));
	for (int i = 0; i < 1500; i++) {
		if (i == 600) /* at speed (a period is 800 um): scale +30000 ppm */
			send((const uint8_t[]){PROTO_SET_ODOMETRIE, 0, 0, 0x6D, 0x60, 0x75, 0x30},
			     7);
		host_tick(&h);
		x1 = board_get_pose(&h.board).x_um - x0;
		d1 = h.board.planner.m.dist_um - d0;
		assert_true(x1 - d1 <= 2 && d1 - x1 <= 2);
	}
	assert_int_equal(h.board.servo.counter.cfg.left_um_per_count_q16, 5301601);
	assert_true(x1 > 100000); /* at the power-on 10 cm/s */
}

/* Repeated corrections keep the estimate within POSITION's range, +-32000 mm, and the robot
 * still takes orders (70 of -32 m would overflow the micrometres: found by fuzz/fuzz_board). */
static void test_set_new_pos_stays_in_range(void **state)
{
	struct sim_field f;
	const uint8_t far[] = {PROTO_SET_NEW_POS, 0x83, 0x00, 0x7D, 0x00, 0, 0}; /* -32000, 32000 */
	int16_t x, y;
	int8_t a;
	uint8_t r;

	(void)state;
	setup_field(&f);
	start(&f);
	for (int i = 0; i < 70; i++) {
		send(far, sizeof(far));
		host_tick(&h);
	}
	position(&x, &y, &a, &r);
	assert_int_equal(x, 32000);
	assert_int_equal(y, -32000);
	goto_mm(31000, -31000);
	assert_int_equal(status(), STATUS_BUSY_TRAJET);
	silence(100);
}

/* The error radius grows with travel. */
static void test_radius_grows(void **state)
{
	struct sim_field f;
	int16_t x, y;
	int8_t a;
	uint8_t r0, r1;

	(void)state;
	setup_field(&f);
	start(&f);
	position(&x, &y, &a, &r0);
	goto_mm(1000, 0);
	run_until_idle(20000);
	position(&x, &y, &a, &r1);
	print_message("radius after 2.3 m: %u mm\n", r1);
	assert_int_equal(r0, 0);
	assert_true(r1 > r0);
}

/* The slow steps late (a port that did not run board_slow() in time): the hand-over that finds
 * them still due counts an overrun and takes nothing; the servo holds the last set points and
 * the period goes on, without a new snapshot; once they run, the board carries on. At one rate
 * (planner_ticks 0) the tick runs them itself: never due. */
static void test_slow_overrun(void **state)
{
	struct sim_field f;

	(void)state;
	setup_field(&f);
	start(&f);
	goto_mm(-1000, -850);
	for (int i = 0; i < 17; i++) {
		port_control_tick(&h.board);
		assert_int_equal(board_slow_due(&h.board), slow_shift != 0);
	}
	/* Tick 1 found tick 0's snapshot still waiting. */
	assert_int_equal(h.board.servo.slow_overruns, slow_shift ? 1 : 0);
	assert_int_equal(h.board.servo.sp_dist.vel_um_s, 0);
	port_slow(&h.board);
	assert_false(board_slow_due(&h.board));
	run_until_idle(20000);
	assert_int_equal(h.board.planner.orders.end_reason, END_REASON_DONE);
	assert_int_equal(h.board.servo.slow_overruns, slow_shift ? 1 : 0);
}

/* The slow steps' rate: 2^0..2^3 ticks, dividing the tick, at 100 Hz or more. */
static void test_slow_shift_range(void **state)
{
	static const struct {
		uint16_t tick_hz;
		uint8_t shift;
		int ok;
	} cases[] = {
		{1000, 0, 1}, {1000, 3, 1}, {1000, 4, 0}, {800, 3, 1},
		{500, 2, 1},  {500, 3, 0},  {100, 1, 0},  {1001, 1, 0},
	};
	struct board_inputs in = {0};
	struct board_config bc;

	(void)state;
	for (size_t i = 0; i < sizeof(cases) / sizeof(cases[0]); i++) {
		board_default_config(&bc);
		bc.tick_hz = cases[i].tick_hz;
		bc.slow_shift = cases[i].shift;
		assert_int_equal(board_init(&h.board, &bc, &in), cases[i].ok ? 0 : -1);
	}
}

int main(void)
{
	const struct CMUnitTest tests[] = {
		cmocka_unit_test(test_goto_arrives),
		cmocka_unit_test(test_goto_turns_first),
		cmocka_unit_test(test_goto_reverse),
		cmocka_unit_test(test_stop),
		cmocka_unit_test(test_replace_is_smooth),
		cmocka_unit_test(test_replace_near_target_at_speed),
		cmocka_unit_test(test_shock_stops),
		cmocka_unit_test(test_goto_panier),
		cmocka_unit_test(test_goto_panier_finds_nothing),
		cmocka_unit_test(test_slip_is_a_motor_problem),
		cmocka_unit_test(test_stuck_motor),
		cmocka_unit_test(test_encoder_cut_is_grave),
		cmocka_unit_test(test_timeout_off_by_default),
		cmocka_unit_test(test_timeout_stops_a_silent_master),
		cmocka_unit_test(test_timeout_writes_keep_it_going),
		cmocka_unit_test(test_timeout_polls_do_not_feed_it),
		cmocka_unit_test(test_half_turn),
		cmocka_unit_test(test_set_new_pos),
		cmocka_unit_test(test_set_new_pos_stays_in_range),
		cmocka_unit_test(test_set_fix_heading_sign),
		cmocka_unit_test(test_set_odometrie),
		cmocka_unit_test(test_set_odometrie_moving),
		cmocka_unit_test(test_radius_grows),
		cmocka_unit_test(test_slow_overrun),
		cmocka_unit_test(test_slow_shift_range),
	};
	int failed;

	slow_shift = 0;
	failed = cmocka_run_group_tests_name("slow steps every tick", tests, NULL, NULL);
	slow_shift = 3;
	failed += cmocka_run_group_tests_name("slow steps every 8th tick", tests, NULL, NULL);
	return failed;
}
