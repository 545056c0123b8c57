/* The host port (see host.h): the HAL answered from the simulator of the current host. */
#include "host.h"

#include <math.h>

#include "hal.h"
#include "port.h"

/* The HAL has no instance argument, as on the real board; the host being single-threaded, it
 * answers for the host whose tick runs: read_sensors() fills it, host_tick() applies the duties. */
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
	bc->uncertainty.track_um = bc->odometry.track_um;
	bc->orders.drive_track_um = (uint32_t)lround(sc->drive_track_mm * 1000.0);
	bc->faults.motor_um_per_count_q16 =
		(uint32_t)lround(two_pi * sc->drive_radius_mm * 1000.0 /
				 (sc->motor.encoder_cpr * sc->motor.gear_ratio) * 65536.0);
	bc->orders.basket_contact_um = (int32_t)lround(sc->basket_sensor_pos.x_mm * 1000.0);
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
	read_sensors(h);
	port_sample(&in);
	return board_init(&h->board, bc, &in);
}

void host_tick(struct host *h)
{
	read_sensors(h);
	port_control_tick(&h->board);
	sim_set_duty(&h->sim, duty[HAL_LEFT], duty[HAL_RIGHT]);
	sim_advance_ns(&h->sim, h->tick_ns);
	h->ticks++;
}

void host_i2c_write(struct host *h, const uint8_t *data, uint8_t n, int stop)
{
	proto_on_write_start(&h->board.proto);
	for (uint8_t i = 0; i < n; i++)
		proto_on_byte(&h->board.proto, data[i]);
	if (stop)
		proto_on_stop(&h->board.proto);
}

void host_i2c_read(struct host *h, uint8_t *out, uint8_t n)
{
	proto_on_read_start(&h->board.proto);
	for (uint8_t i = 0; i < n; i++)
		out[i] = proto_read_byte(&h->board.proto);
	proto_on_stop(&h->board.proto);
}
