/* The calibration kept in the port's storage (see port_nvm.h). */
#include "port_nvm.h"

#include "hal.h"

static int same(const struct board_calibration *a, const struct board_calibration *b)
{
	return a->ratio_ppm == b->ratio_ppm && a->scale_ppm == b->scale_ppm &&
	       a->track_10um == b->track_10um;
}

int port_nvm_load(struct port_nvm *s, struct board *b)
{
	struct board_calibration cal;
	int err;

	s->have = 0;
	s->pos = CALIB_STORE_SIZE;
	if (hal_nvm_size() < PORT_NVM_CALIB_OFFSET + CALIB_STORE_SIZE ||
	    hal_nvm_read(PORT_NVM_CALIB_OFFSET, s->rec, CALIB_STORE_SIZE) != 0)
		err = -1;
	else
		err = calib_store_decode(s->rec, &cal);
	if (err == 0)
		err = board_set_calibration(b, &cal);
	if (err == 0) {
		/* What the storage holds is installed: nothing to write until it changes. */
		s->stored = cal;
		s->have = 1;
	}
	s->loaded = (int8_t)(err < -128 ? -128 : err);
	return err;
}

void port_nvm_poll(struct port_nvm *s, const struct board *b)
{
	/* b->planner.calibration changes only in the planner (SET_ODOMETRIE), which run in this
	 * context: no torn read. A calibration that comes while a record is half written
	 * restarts the write with its own record. */
	if (b->planner.calibrated && (!s->have || !same(&b->planner.calibration, &s->stored))) {
		s->stored = b->planner.calibration;
		s->have = 1;
		calib_store_encode(&s->stored, s->rec);
		s->pos = 0;
	}
	while (s->pos < CALIB_STORE_SIZE && !hal_nvm_busy()) {
		int err = hal_nvm_write_byte((uint16_t)(PORT_NVM_CALIB_OFFSET + s->pos),
					     s->rec[s->pos]);

		if (err == -2)
			break; /* busy after all: the next call */
		/* Written, or outside the storage (port_nvm_load() then said -1): go on. */
		s->pos++;
	}
}

uint8_t port_nvm_pending(const struct port_nvm *s)
{
	return s->pos < CALIB_STORE_SIZE;
}
