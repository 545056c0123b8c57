/* The A/B rule over two areas of records (see calib_log.h). */
#include "calib_log.h"

static int blank(const uint8_t *p)
{
	for (uint8_t i = 0; i < CALIB_STORE_SIZE; i++)
		if (p[i] != 0xFFu)
			return 0;
	return 1;
}

void calib_log_scan(calib_log_read read, void *ctx, uint8_t area, uint16_t slots,
		    struct calib_log_area *l)
{
	uint8_t buf[CALIB_STORE_SIZE];
	struct board_calibration cal;

	l->next = 0;
	l->found = 0;
	l->gen = 0;
	l->err = CALIB_STORE_BLANK;
	for (uint16_t i = 0; i < slots; i++) {
		const uint8_t *p = read(ctx, area, i, buf);
		int e;

		if (!p) {
			if (!l->found)
				l->err = CALIB_LOG_UNREADABLE;
			continue;
		}
		if (blank(p))
			continue;
		l->next = (uint16_t)(i + 1u);
		e = calib_store_decode(p, &cal);
		if (e == 0 || l->err != 0)
			l->err = e; /* the last valid record, or the last refusal if none */
		if (e == 0) {
			l->cal = cal;
			l->gen = calib_store_generation(p);
			l->found = 1;
		}
	}
}

uint8_t calib_log_pick(const struct calib_log_area l[CALIB_LOG_AREAS])
{
	if (l[0].found && l[1].found)
		return calib_store_newer(l[1].gen, l[0].gen);
	if (l[0].found || l[1].found)
		return l[1].found;
	return l[1].next < l[0].next;
}
