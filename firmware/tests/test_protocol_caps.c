/* The protocol layer of a build that leaves issue 31's extensions out (CONFIG_MOTION_* 0, as a
 * port short of budget would): their capability bits are clear in VERSION, and their frames are
 * rejected UNSUPPORTED, changing nothing. The real protocol.c, compiled here with the options. */
#define CONFIG_MOTION_PAUSE 0
#define CONFIG_MOTION_SPEED_SCALE 0
#define CONFIG_MOTION_QUEUE 0
#define CONFIG_MOTION_CORNERS 0
#include "../core/protocol.c"

#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>

#include <cmocka.h>

static void write_frame(struct proto *p, const uint8_t *b, uint8_t n)
{
	proto_master_write(p, b, n, 1);
}

static uint8_t last_reject_reason(struct proto *p)
{
	uint8_t r[3];

	write_frame(p, (const uint8_t[]){PROTO_LAST_REJECT}, 1);
	proto_master_read(p, r, 3);
	return r[0];
}

static void test_version_says_what_is_left_out(void **state)
{
	struct proto p;
	uint8_t v[4];
	uint16_t caps;

	(void)state;
	proto_init(&p);
	write_frame(&p, (const uint8_t[]){PROTO_VERSION}, 1);
	proto_master_read(&p, v, 4);
	caps = (uint16_t)((v[2] << 8) | v[3]);
	assert_int_equal(caps & (CAP_PAUSE | CAP_SPEED_SCALE | CAP_QUEUE | CAP_CORNERS), 0);
	assert_int_equal(caps, CAP_PEC | CAP_STOP | CAP_LAST_REJECT | CAP_DEBUG | CAP_TIMEOUT |
				       CAP_HEARTBEAT | CAP_FIX | CAP_QUIET_SERVO);
}

static void test_the_frames_left_out_are_unsupported(void **state)
{
	static const struct {
		uint8_t len;
		uint8_t bytes[6];
	} frames[] = {
		{1, {PROTO_PAUSE}},
		{1, {PROTO_RESUME}},
		{1, {PROTO_MOTION}},
		{2, {PROTO_SET_SPEED_SCALE, 50}},
		{2, {PROTO_SET_CORNER, 30}},
		{6, {PROTO_GOTO, 0, 100, 0, 100, PROTO_OPT_APPEND}},
		{6, {PROTO_GOTO, 0, 100, 0, 100, PROTO_OPT_PASS_THROUGH}},
		{3, {PROTO_GOTO_REVERSE, 100, PROTO_OPT_APPEND}},
		{3, {PROTO_GOTO_PANIER, 10, PROTO_OPT_APPEND}},
	};
	struct proto p;
	struct proto_msg m;
	uint8_t status;

	(void)state;
	for (size_t i = 0; i < sizeof(frames) / sizeof(frames[0]); i++) {
		proto_init(&p);
		write_frame(&p, frames[i].bytes, frames[i].len);
		assert_int_equal(proto_poll(&p, &m), 0);
		proto_master_read(&p, &status, 1);
		assert_int_equal(status, STATUS_COMMANDE_REJETEE);
		assert_int_equal(last_reject_reason(&p), REJECT_UNSUPPORTED);
	}
	/* The 2002 frames still pass. */
	proto_init(&p);
	write_frame(&p, (const uint8_t[]){PROTO_GOTO_REVERSE, 100}, 2);
	assert_int_equal(proto_poll(&p, &m), 1);
}

int main(void)
{
	const struct CMUnitTest tests[] = {
		cmocka_unit_test(test_version_says_what_is_left_out),
		cmocka_unit_test(test_the_frames_left_out_are_unsupported),
	};

	return cmocka_run_group_tests(tests, NULL, NULL);
}
