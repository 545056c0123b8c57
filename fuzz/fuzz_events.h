/* The byte language both fuzz targets read (fuzz/README.md): each input is a sequence of events
 * as the I2C interrupt and the control tick see them. An event is one byte, its low 3 bits the
 * kind and its high 5 bits a count n (1..32); some kinds take bytes after it. A cut-short input
 * simply ends. fuzz/seed_corpus.py writes the same language from protocol/vectors.toml. The
 * helpers below are shared by both targets. */
#ifndef ASSERV_FUZZ_EVENTS_H
#define ASSERV_FUZZ_EVENTS_H

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>

#include "protocol.h"

enum fuzz_kind {
	FUZZ_START_W = 0, /* own address + write: proto_on_write_start() */
	FUZZ_DATA = 1,    /* n data bytes follow, each proto_on_byte() */
	FUZZ_START_R = 2, /* own address + read: proto_on_read_start() */
	FUZZ_READ = 3,    /* n bytes read by the master: proto_read_byte() */
	FUZZ_STOP = 4,    /* n odd: STOP, proto_on_stop(); n even: a repeated start as the AVR's
			   * TWI reports it, before the next address: proto_on_restart() */
	FUZZ_ABORT = 5,   /* bus error: proto_on_abort() */
	FUZZ_TICK = 6,    /* the control side: see each target */
	FUZZ_ENV = 7,     /* the control side: see each target */
};

struct fuzz_input {
	const uint8_t *p;
	size_t n;
};

/* The next byte, or 0 with *ok cleared at the end of the input. */
static inline uint8_t fuzz_byte(struct fuzz_input *in, int *ok)
{
	if (in->n == 0) {
		*ok = 0;
		return 0;
	}
	in->n--;
	return *in->p++;
}

/* The next event: its kind (enum fuzz_kind) and its count n (1..32); 0 at the end of the
 * input. */
static inline int fuzz_event(struct fuzz_input *in, uint8_t *kind, uint8_t *n)
{
	int ok = 1;
	uint8_t ev = fuzz_byte(in, &ok);

	*kind = (uint8_t)(ev & 7u);
	*n = (uint8_t)((ev >> 3) + 1u);
	return ok;
}

/* A failed property: say which and abort, so that libFuzzer keeps the input as a crash. */
static inline void fuzz_fail(const char *file, int line, const char *what)
{
	fprintf(stderr, "%s:%d: property violated: %s\n", file, line, what);
	abort();
}

/* UBSan's defaults for the targets: any report stops the run (the checks are compiled
 * recoverable only for fuzz/known-ub.supp). */
const char *__ubsan_default_options(void);
const char *__ubsan_default_options(void)
{
	return "halt_on_error=1:print_stacktrace=1";
}

#define FUZZ_CHECK(cond)                                                                           \
	do {                                                                                       \
		if (!(cond))                                                                       \
			fuzz_fail(__FILE__, __LINE__, #cond);                                      \
	} while (0)

/* Two snapshots field by field (their padding may differ). */
static inline int fuzz_snap_equal(const struct proto_snapshot *a, const struct proto_snapshot *b)
{
	const struct proto_debug *x = &a->debug, *y = &b->debug;

	return a->x_mm == b->x_mm && a->y_mm == b->y_mm && a->angle_2deg == b->angle_2deg &&
	       a->radius_mm == b->radius_mm && a->status == b->status && a->sensors == b->sensors &&
	       x->tick == y->tick && x->heading_cdeg == y->heading_cdeg &&
	       x->speed_mm_s == y->speed_mm_s && x->turn_rate_cdeg_s == y->turn_rate_cdeg_s &&
	       x->dist_err_um == y->dist_err_um && x->angle_err_um == y->angle_err_um &&
	       x->duty_left_q15 == y->duty_left_q15 && x->duty_right_q15 == y->duty_right_q15 &&
	       x->current_left_ma == y->current_left_ma &&
	       x->current_right_ma == y->current_right_ma && x->order_state == y->order_state &&
	       x->end_reason == y->end_reason;
}

#endif
