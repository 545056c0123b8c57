/* The host port (see host.h): the HAL answered from the simulator of the current host. */
#include "host.h"

#include <math.h>
#include <string.h>

#include "hal.h"
#include "port.h"

/* The HAL has no instance argument, as on the real board; the host being single-threaded, it
 * answers for the host whose tick runs: read_sensors() fills it, host_tick() applies the duties.
 * The storage is each host's own (struct nvm_bytes_dev, passed by nvm_bytes.c). */
static struct sim_sensors sensors;
static int16_t duty[2];

uint16_t hal_encoder_free(enum hal_side side)
{
	return sensors.enc_count[side];
}

uint16_t hal_encoder_motor(enum hal_side side)
{
	return sensors.motor_count[side];
}

int16_t hal_motor_current_ma(enum hal_side side)
{
	int32_t ma = sensors.current_mA[side];

	return (int16_t)(ma > 32767 ? 32767 : ma < -32767 ? -32767 : ma);
}

void hal_motor_set(enum hal_side side, int16_t duty_q15)
{
	duty[side] = duty_q15;
}

uint8_t hal_shock_read(void)
{
	return sensors.shock_mask;
}

uint8_t hal_basket_contact(void)
{
	return sensors.basket ? 1 : 0;
}

uint8_t hal_line_read(void)
{
	return sensors.line_mask;
}

uint16_t nvm_bytes_dev_size(struct nvm_bytes_dev *dev)
{
	(void)dev;
	return HOST_NVM_SIZE;
}

int nvm_bytes_dev_read(struct nvm_bytes_dev *dev, uint16_t offset, uint8_t *buf, uint16_t n)
{
	if ((uint32_t)offset + n > HOST_NVM_SIZE)
		return -1;
	memcpy(buf, &dev->mem[offset], n);
	return 0;
}

uint8_t nvm_bytes_dev_busy(struct nvm_bytes_dev *dev)
{
	(void)dev;
	return 0; /* written at once */
}

int nvm_bytes_dev_write(struct nvm_bytes_dev *dev, uint16_t offset, uint8_t value)
{
	if (offset >= HOST_NVM_SIZE)
		return -1;
	dev->mem[offset] = value;
	return 0;
}

void hal_i2c_slave_init(uint8_t address)
{
	(void)address; /* the host's bus calls the protocol layer directly */
}

void hal_tick_start(uint16_t rate_hz)
{
	(void)rate_hz; /* host_tick() is the lockstep */
}

void host_board_config(const struct sim_config *sc, const struct sim_field *f,
		       struct board_config *bc)
{
	const double two_pi = 6.283185307179586;
	uint8_t n = 0;

	board_default_config(bc);
	bc->odometry.left_um_per_count_q16 = bc->odometry.right_um_per_count_q16 =
		(uint32_t)lround(two_pi * sc->enc_radius_mm * 1000.0 / sc->enc_cpr * 65536.0);
	bc->odometry.track_um = (uint32_t)lround(sc->enc_track_mm * 1000.0);
	bc->orders.drive_track_um = (uint32_t)lround(sc->drive_track_mm * 1000.0);
	bc->faults.motor_um_per_count_q16 =
		(uint32_t)lround(two_pi * sc->drive_radius_mm * 1000.0 /
				 (sc->motor.encoder_cpr * sc->motor.gear_ratio) * 65536.0);
	bc->orders.basket_contact_um = (int32_t)lround(sc->basket_sensor_pos.x_mm * 1000.0);
	bc->orders.grip_um_s2 =
		(int32_t)lround(sc->friction_coeff * sc->drive_weight_share * 9.80665 * 1e6);
	bc->orders.rot_grip_q8 = (uint16_t)lround(
		4.0 * sc->yaw_inertia_kg_m2 /
		(sc->mass_kg * sc->drive_track_mm * sc->drive_track_mm * 1e-6) * 256.0);
	for (int i = 0; i < f->obstacle_count && n < ORDERS_MAX_BASKETS; i++) {
		const struct sim_obstacle *o = &f->obstacles[i];

		if (o->kind != SIM_OBSTACLE_BASKET || o->shape != SIM_SHAPE_CIRCLE)
			continue;
		bc->orders.baskets[n].x_um = (int32_t)lround(o->x_mm * 1000.0);
		bc->orders.baskets[n].y_um = (int32_t)lround(o->y_mm * 1000.0);
		bc->orders.baskets[n].radius_um = (int32_t)lround(o->radius_mm * 1000.0);
		n++;
	}
	bc->orders.n_baskets = n;
	/* Recalibration: the outline's front edge, the line sensors and the field's lines and
	 * borders as the simulator has them (the board's frame is the encoder axis midpoint). */
	bc->orders.front_um = (int32_t)lround(
		(sc->outline_offset_x_mm + sc->outline_length_mm / 2 - sc->enc_offset_x_mm) *
		1000.0);
	bc->orders.borders = f->borders;
	bc->orders.half_length_um = (int32_t)lround(f->length_mm * 500.0);
	bc->orders.half_width_um = (int32_t)lround(f->width_mm * 500.0);
	bc->recal.n_sensors = sc->line_sensor_count < RECAL_MAX_SENSORS ? sc->line_sensor_count
									: RECAL_MAX_SENSORS;
	for (uint8_t i = 0; i < bc->recal.n_sensors; i++) {
		bc->recal.sensors[i].x_um =
			(int32_t)lround((sc->line_sensor[i].x_mm - sc->enc_offset_x_mm) * 1000.0);
		bc->recal.sensors[i].y_um = (int32_t)lround(sc->line_sensor[i].y_mm * 1000.0);
	}
	n = 0;
	for (int i = 0; i < f->line_count && n < RECAL_MAX_LINES; i++) {
		const struct sim_line *l = &f->lines[i];

		bc->recal.lines[n].x0_um = (int32_t)lround(l->x0_mm * 1000.0);
		bc->recal.lines[n].y0_um = (int32_t)lround(l->y0_mm * 1000.0);
		bc->recal.lines[n].x1_um = (int32_t)lround(l->x1_mm * 1000.0);
		bc->recal.lines[n].y1_um = (int32_t)lround(l->y1_mm * 1000.0);
		bc->recal.lines[n].width_um = (int32_t)lround(l->width_mm * 1000.0);
		n++;
	}
	bc->recal.n_lines = n;
	/* The board believes the robot is where the simulator's configuration puts it (before
	 * any start error a benchmark adds to the truth). */
	bc->start.x_um = (int32_t)lround(sc->start.x_mm * 1000.0);
	bc->start.y_um = (int32_t)lround(sc->start.y_mm * 1000.0);
	bc->start.heading_turn32 =
		(uint32_t)(int64_t)llround(sc->start.heading_rad * (4294967296.0 / two_pi));
}

static void read_sensors(struct host *h)
{
	sim_read_sensors(&h->sim, &sensors);
}

int host_init(struct host *h, const struct board_config *bc, const struct sim_config *sc,
	      const struct sim_field *f)
{
	struct board_inputs in;
	int err;

	/* The robot starts at sc->start (where the team put it, start error included); the board
	 * believes bc->start. */
	err = sim_init(&h->sim, sc, f);
	if (err)
		return err;
	h->tick_ns = 1000000000u / bc->tick_hz;
	h->ticks = 0;
	h->now_ns = 0;
	memset(h->storage.mem, 0xFF, sizeof(h->storage.mem));
	nvm_bytes_init(&h->nvm, &h->storage);
	read_sensors(h);
	port_sample(&in);
	port_sample_period(&in); /* the motor counts and currents to start from, as the AVR's */
	err = board_restart(&h->board, bc, &in, RESET_CAUSE_POWER_ON, 0);
	if (err)
		return err;
	hal_nvm_load(&h->nvm, &h->board); /* erased: uncalibrated */
	return 0;
}

int host_nvm_set(struct host *h, const uint8_t *data, uint16_t n)
{
	if (n > HOST_NVM_SIZE)
		return -1;
	memset(h->storage.mem, 0xFF, sizeof(h->storage.mem));
	if (n)
		memcpy(h->storage.mem, data, n);
	return 0;
}

/* The board starts again with a cause, after down_ms of the robot coasting. */
static int restart(struct host *h, uint8_t cause, uint16_t down_ms)
{
	struct board_config cfg = h->board.cfg;
	struct board_inputs in;
	int err;
	uint64_t skipped = (uint64_t)down_ms * 1000000u / h->tick_ns; /* ticks the board misses */

	duty[HAL_LEFT] = duty[HAL_RIGHT] = 0;
	sim_set_duty(&h->sim, 0, 0);
	sim_advance_ns(&h->sim, skipped * h->tick_ns);
	h->now_ns += skipped * h->tick_ns;
	h->ticks += skipped;
	read_sensors(h);
	port_sample(&in);
	port_sample_period(&in);
	err = board_restart(&h->board, &cfg, &in, cause, down_ms);
	duty[HAL_LEFT] = duty[HAL_RIGHT] = 0;
	sim_set_duty(&h->sim, 0, 0);
	if (err)
		return err;
	hal_nvm_load(&h->nvm, &h->board);
	return 0;
}

int host_power_cycle(struct host *h)
{
	return restart(h, RESET_CAUSE_POWER_ON, 0);
}

int host_reset(struct host *h, uint8_t cause, int keep_ram, uint16_t down_ms)
{
	if (cause == RESET_CAUSE_POWER_ON)
		return host_power_cycle(h);
	if (!keep_ram) { /* what a lost RAM holds: a pattern of the clock */
		uint8_t *k = (uint8_t *)&h->board.keep;

		for (size_t i = 0; i < sizeof(h->board.keep); i++)
			k[i] = (uint8_t)((h->now_ns >> (i % 8u)) * 131u + i * 29u);
	}
	return restart(h, cause, down_ms);
}

/* The control tick at the current instant: sensors, board_tick(), the new duties held by the
 * physics until the next tick. */
static void control_tick(struct host *h)
{
	read_sensors(h);
	port_control_tick(&h->board);
	port_slow(&h->board);
	hal_nvm_poll(&h->nvm, &h->board);
	sim_set_duty(&h->sim, duty[HAL_LEFT], duty[HAL_RIGHT]);
	h->ticks++;
}

void host_tick(struct host *h)
{
	control_tick(h);
	sim_advance_ns(&h->sim, h->tick_ns);
	h->now_ns += h->tick_ns; /* same clock as host_advance_ns(): call it on a tick boundary */
}

void host_i2c_write(struct host *h, const uint8_t *data, uint8_t n, int stop)
{
	proto_master_write(&h->board.proto, data, n, stop);
}

void host_i2c_read(struct host *h, uint8_t *out, uint8_t n)
{
	proto_master_read(&h->board.proto, out, n);
}

static double turn32_deg(uint32_t heading_turn32)
{
	return (double)(int32_t)heading_turn32 * (360.0 / 4294967296.0);
}

static void record(const struct host *h, struct host_sample *r)
{
	const double rad_deg = 57.29577951308232;
	const struct board *b = &h->board;
	struct sim_truth t;
	struct odometry_pose est;
	double half_track_um = b->cfg.orders.drive_track_um / 2.0;

	sim_get_truth(&h->sim, &t);
	est = board_get_pose(b);
	r->t_s = h->now_ns * 1e-9;
	r->x_mm = t.odo_pose.x_mm;
	r->y_mm = t.odo_pose.y_mm;
	r->heading_deg = t.odo_pose.heading_rad * rad_deg;
	r->est_x_mm = est.x_um * 1e-3;
	r->est_y_mm = est.y_um * 1e-3;
	r->est_heading_deg = turn32_deg(est.heading_turn32);
	r->radius_mm = uncertainty_get_radius_mm(&b->planner.uncertainty);
	r->v_mm_s = t.v_mm_s;
	r->omega_deg_s = t.omega_rad_s * rad_deg;
	r->v_set_mm_s = b->servo.sp_dist.vel_um_s * 1e-3;
	r->omega_set_deg_s = b->servo.sp_angle.vel_um_s / half_track_um * rad_deg;
	r->duty_left = duty[HAL_LEFT] / 32768.0;
	r->duty_right = duty[HAL_RIGHT] / 32768.0;
	r->current_left_A = t.current_A[SIM_LEFT];
	r->current_right_A = t.current_A[SIM_RIGHT];
	r->contact_force_N = t.contact_force_N;
	r->status = proto_status(&b->proto); /* what CHECK_BUSY answers now */
	r->order_state = b->planner.orders.state;
	r->shocks = b->planner.shocks;
}

uint64_t host_advance_ns(struct host *h, uint64_t duration_ns, struct host_sample *buf,
			 uint32_t cap, uint32_t *n_out)
{
	uint64_t end_ns = h->now_ns + duration_ns;
	uint64_t start_ns = h->now_ns;
	uint32_t n = 0;

	while (h->now_ns < end_ns) {
		uint64_t next_ns;

		if (h->now_ns == h->ticks * h->tick_ns) {
			if (buf && n >= cap)
				break; /* full: the caller empties buf before this tick runs */
			control_tick(h);
			if (buf)
				record(h, &buf[n++]);
		}
		next_ns = h->ticks * h->tick_ns;
		if (next_ns > end_ns)
			next_ns = end_ns;
		sim_advance_ns(&h->sim, next_ns - h->now_ns);
		h->now_ns = next_ns;
	}
	if (n_out)
		*n_out = n;
	return h->now_ns - start_ns;
}
