/* hal_nvm.h on byte storage: two slots written in turn (see nvm_bytes.h). */
#include "nvm_bytes.h"

#include "calib_log.h"

#define SPOILT 0xFFu /* byte 0 while a record is written: not the magic's 'a' */

static uint16_t slot_offset(uint8_t slot)
{
	return (uint16_t)(NVM_BYTES_CALIB_OFFSET + slot * CALIB_STORE_SIZE);
}

void nvm_bytes_init(struct hal_nvm *s, struct nvm_bytes_dev *dev)
{
	s->dev = dev;
	s->have = 0;
	s->pos = NVM_BYTES_STEPS;
}

/* calib_log.h's reader: slot i of area a (each area one slot) of the storage ctx, copied into
 * buf. */
static const uint8_t *read_slot(void *ctx, uint8_t area, uint16_t i, uint8_t buf[CALIB_STORE_SIZE])
{
	struct nvm_bytes_dev *dev = ctx;

	(void)i;
	if (nvm_bytes_dev_size(dev) < slot_offset(NVM_BYTES_SLOTS) ||
	    nvm_bytes_dev_read(dev, slot_offset(area), buf, CALIB_STORE_SIZE) != 0)
		return 0;
	return buf;
}

int hal_nvm_load(struct hal_nvm *s, struct board *b)
{
	struct calib_log_area l[CALIB_LOG_AREAS];
	int err;

	s->have = 0;
	s->pos = NVM_BYTES_STEPS;
	calib_log_scan(read_slot, s->dev, 0, 1, &l[0]);
	calib_log_scan(read_slot, s->dev, 1, 1, &l[1]);
	if (l[0].found || l[1].found) {
		s->slot = calib_log_pick(l);
		s->gen = l[s->slot].gen;
		err = board_set_calibration(b, &l[s->slot].cal);
	} else {
		/* None valid: the first record goes into slot 0, generation 0. */
		s->slot = 1;
		s->gen = 0xFFu;
		err = l[0].err;
	}
	if (err == 0) {
		/* What the storage holds is installed: nothing to write until it changes. */
		s->stored = l[s->slot].cal;
		s->have = 1;
	}
	s->loaded = (int8_t)(err < -128 ? -128 : err);
	return err;
}

/* 1 when the slot's byte 0 reads as the magic's 'a'. A write cut by a power-off may leave the
 * byte it writes anything, 'a' too: byte 0 is spoilt first only when it is 'a', so that such a
 * cut cannot make a slot decode that did not (bytes 1 to 15 that are a whole record, left by
 * a cut of an earlier record's last write, behind an 'a' the cut made). No write is in progress
 * (the caller checked): the read does not wait. */
static uint8_t magic_first(const struct hal_nvm *s)
{
	uint8_t v;

	return nvm_bytes_dev_read(s->dev, slot_offset(s->slot), &v, 1) == 0 &&
	       v == CALIB_STORE_MAGIC0;
}

/* The byte of write step i: byte 0 spoilt, bytes 1 to 15, then byte 0. */
static uint8_t step_byte(const struct hal_nvm *s, uint8_t i, uint8_t *at)
{
	if (i == 0) {
		*at = 0;
		return SPOILT;
	}
	*at = i == CALIB_STORE_SIZE ? 0 : i;
	return s->rec[*at];
}

void hal_nvm_poll(struct hal_nvm *s, const struct board *b)
{
	/* b->planner.calibration changes only in the planner (SET_ODOMETRIE), which run in this
	 * context: no torn read. A calibration that comes while a record is half written
	 * restarts the write with its own record, in the same slot: the other one still holds
	 * the newest complete record. */
	if (b->planner.calibrated &&
	    (!s->have || !calib_store_same(&b->planner.calibration, &s->stored))) {
		if (s->pos == NVM_BYTES_STEPS) {
			/* The previous record is whole: the new one goes into the other slot. */
			s->slot ^= 1u;
			s->gen++;
		}
		s->stored = b->planner.calibration;
		s->have = 1;
		calib_store_encode(&s->stored, s->gen, s->rec);
		s->pos = 0;
	}
	while (s->pos < NVM_BYTES_STEPS && !nvm_bytes_dev_busy(s->dev)) {
		uint8_t at;
		uint8_t v;
		int err;

		if (s->pos == 0 && !magic_first(s)) {
			s->pos = 1; /* byte 0 is not 'a': nothing to spoil */
			continue;
		}
		v = step_byte(s, s->pos, &at);
		err = nvm_bytes_dev_write(s->dev, (uint16_t)(slot_offset(s->slot) + at), v);
		if (err == -2)
			break; /* busy after all: the next call */
		/* Written, or outside the storage (hal_nvm_load() then said so): go on. */
		s->pos++;
	}
}

uint8_t hal_nvm_pending(const struct hal_nvm *s)
{
	return s->pos < NVM_BYTES_STEPS;
}
