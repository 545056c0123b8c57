/* libFuzzer target: the whole board (board_tick() and the protocol layer) fed I2C events in any
 * order and control ticks on a small robot model (fuzz_events.h). Two boards run in lockstep on
 * the same sensor inputs: board A receives every bus event, board B only the frames A accepted,
 * whole, and as many transactions (address-only writes for the others). Besides the sanitizers, it
 * checks at every tick:
 *   - a rejected frame, a read, an aborted transaction change nothing of the motion: A and B
 *     give the same duties, the same published snapshot (pose, status, telemetry) and the same
 *     pose to the micrometre;
 *   - once PB_GRAVE or PB_MOTEUR is published both duties are 0: the motors never keep driving
 *     into a fault;
 *   - the status is consistent: bit 7 clear, BUSY_GOTO_PANIER only with BUSY_TRAJET, no end bit
 *     and no PB_GRAVE while a trajectory runs, the published status is the core's (with the slow
 *     steps at every tick; otherwise it is that of the last hand-over).
 * An input of odd length runs the slow steps every 8th tick (slow_shift 3, board.h), after the
 * tick as the simulator does; one of even length, at every tick.
 * TICK (kind 6) runs n control ticks. ENV (kind 7) sets the disturbances of the next ticks from
 * the next two bytes: the shock sensors, then the flags below. */
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include "board.h"
#include "fuzz_events.h"

enum env_flag {
	ENV_BASKET = 1u << 0,      /* the basket switch is closed */
	ENV_CUT_FREE_L = 1u << 1,  /* the left free wheel's encoder stops counting */
	ENV_CUT_FREE_R = 1u << 2,  /* the right one */
	ENV_STALL_L = 1u << 3,     /* the left motor is locked */
	ENV_BLOCKED = 1u << 4,     /* the robot is blocked: drive wheels spin, free wheels still */
	ENV_OVERCURRENT = 1u << 5, /* both currents read 9 A */
	ENV_GLITCH = 1u << 6,      /* the left free encoder jumps 3000 counts once */
	ENV_CUT_MOTOR_L = 1u << 7, /* the left motor encoder stops counting */
};

/* The robot: each drive wheel follows its duty with a first-order lag (1.64 m/s at full duty,
 * as the reference robot), the free wheels follow the body. Travels in um * 2^16. */
struct plant {
	int32_t v_um_tick[2];
	int64_t drive_q16[2], free_q16[2];
	uint16_t free_jump;
	uint8_t shocks, flags;
};

struct frame {
	uint8_t bytes[64];
	uint8_t n;
};

static struct board a, b;
static struct plant pl;
static struct frame fr;

static uint16_t counts(int64_t travel_q16, uint32_t um_per_count_q16)
{
	return (uint16_t)(uint64_t)(travel_q16 / (int64_t)um_per_count_q16);
}

static void sample(struct board_inputs *in, const struct board_outputs *last)
{
	const struct board_config *c = &a.cfg;

	for (int s = 0; s < 2; s++) {
		int32_t ma = last->duty_q15[s] / 4; /* 8 A at full duty */

		in->free_count[s] = counts(pl.free_q16[s], c->odometry.left_um_per_count_q16);
		in->motor_count[s] = counts(pl.drive_q16[s], c->faults.motor_um_per_count_q16);
		in->current_ma[s] = (int16_t)((pl.flags & ENV_OVERCURRENT) ? 9000 : ma);
	}
	in->free_count[0] = (uint16_t)(in->free_count[0] + pl.free_jump);
	in->shocks = pl.shocks;
	in->basket = (pl.flags & ENV_BASKET) ? 1 : 0;
	in->lines = (uint8_t)(pl.shocks >> 4);
}

static void step_plant(const struct board_outputs *out)
{
	const struct board_config *c = &a.cfg;
	int64_t v[2], center, half_diff;

	for (int s = 0; s < 2; s++) {
		int32_t target = out->duty_q15[s] * 1640 / 32767;

		pl.v_um_tick[s] += (target - pl.v_um_tick[s]) / 4;
		if (s == 0 && (pl.flags & ENV_STALL_L))
			pl.v_um_tick[s] = 0;
		v[s] = (int64_t)pl.v_um_tick[s] * 65536;
		if (!(s == 0 && (pl.flags & ENV_CUT_MOTOR_L)))
			pl.drive_q16[s] += v[s];
	}
	if (pl.flags & ENV_BLOCKED)
		return;
	center = (v[0] + v[1]) / 2;
	half_diff = (v[1] - v[0]) / 2 * (int64_t)c->odometry.track_um /
		    (int64_t)c->orders.drive_track_um;
	if (!(pl.flags & ENV_CUT_FREE_L))
		pl.free_q16[0] += center - half_diff;
	if (!(pl.flags & ENV_CUT_FREE_R))
		pl.free_q16[1] += center + half_diff;
}

static const struct proto_snapshot *published(const struct board *x)
{
	return &x->proto.snap[x->proto.snap_index & 1u];
}

static void check_tick(const struct board_outputs *oa, const struct board_outputs *ob)
{
	struct odometry_pose pa = board_get_pose(&a);
	struct odometry_pose pb = board_get_pose(&b);
	const uint8_t end_bits = STATUS_CHOC_PANIER | STATUS_CHOC_BORD | STATUS_PB_MOTEUR;
	const struct proto_snapshot *pub = published(&a);
	uint8_t s = a.cfg.slow_shift ? pub->status : a.planner.status;

	FUZZ_CHECK(oa->duty_q15[0] == ob->duty_q15[0] && oa->duty_q15[1] == ob->duty_q15[1]);
	FUZZ_CHECK(fuzz_snap_equal(published(&a), published(&b)));
	FUZZ_CHECK(a.planner.status == b.planner.status);
	FUZZ_CHECK(pa.x_um == pb.x_um && pa.y_um == pb.y_um &&
		   pa.heading_turn32 == pb.heading_turn32);
	FUZZ_CHECK(odometry_get_heading_turn32(&a.servo.counter) ==
		   odometry_get_heading_turn32(&b.servo.counter));

	if (s & (STATUS_PB_GRAVE | STATUS_PB_MOTEUR))
		FUZZ_CHECK(oa->duty_q15[0] == 0 && oa->duty_q15[1] == 0);
	FUZZ_CHECK((s & (0x80u | STATUS_COMMANDE_REJETEE)) == 0);
	if (s & STATUS_BUSY_GOTO_PANIER)
		FUZZ_CHECK(s & STATUS_BUSY_TRAJET);
	if (s & STATUS_BUSY_TRAJET)
		FUZZ_CHECK((s & (end_bits | STATUS_PB_GRAVE)) == 0);
	/* What MOTION's queue adds to the published status (motion_publish()): busy while an
	 * order waits, the last ending's bits while a queued order runs. */
	FUZZ_CHECK(pub->status == (s | (a.planner.motion.count ? STATUS_BUSY_TRAJET : 0u) |
				   (a.planner.motion.running && a.planner.motion.from_queue
					    ? a.planner.motion.stale_bits
					    : 0u)));
	FUZZ_CHECK((proto_status(&a.proto) & 0x80u) == 0);
}

static void tick(void)
{
	struct board_inputs in;
	struct board_outputs oa, ob;

	/* The master's activity is the same for both: every transaction A saw counts for B too,
	 * as an address-only write, which is not a frame (SET_TIMEOUT counts only accepted writes,
	 * which B receives as A does; the transaction counters are kept equal all the same). */
	while (b.proto.transactions != a.proto.transactions) {
		proto_on_write_start(&b.proto);
		proto_on_stop(&b.proto);
	}
	memset(&in, 0, sizeof(in));
	sample(&in, &a.servo.last_out);
	board_tick(&a, &in, &oa);
	board_tick(&b, &in, &ob);
	check_tick(&oa, &ob);
	FUZZ_CHECK(board_slow_due(&a) == board_slow_due(&b));
	if (board_slow_due(&a)) {
		board_slow(&a);
		board_slow(&b);
	}
	step_plant(&oa);
	if (pl.flags & ENV_GLITCH) {
		pl.free_jump = (uint16_t)(pl.free_jump + 3000u);
		pl.flags &= (uint8_t)~ENV_GLITCH;
	}
}

/* A's write ends with this event: B receives the frame whole if A accepted it into its queue. */
static void end_write(void (*event)(struct proto *))
{
	struct proto judged = a.proto;
	uint8_t head = a.proto.head, head_b = b.proto.head;

	if (event == proto_on_abort)
		proto_on_abort(&judged);
	else
		proto_on_stop(&judged);
	event(&a.proto);
	FUZZ_CHECK(a.proto.head == judged.head);
	if (a.proto.head == head)
		return;
	proto_on_write_start(&b.proto);
	for (uint8_t i = 0; i < fr.n; i++)
		proto_on_byte(&b.proto, fr.bytes[i]);
	proto_on_stop(&b.proto);
	FUZZ_CHECK(b.proto.head == (uint8_t)(head_b + 1u));
}

static void start(uint8_t slow_shift)
{
	struct board_config c;
	struct board_inputs in;

	board_default_config(&c);
	c.slow_shift = slow_shift;
	memset(&pl, 0, sizeof(pl));
	memset(&fr, 0, sizeof(fr));
	memset(&in, 0, sizeof(in));
	FUZZ_CHECK(board_init(&a, &c, &in) == 0);
	FUZZ_CHECK(board_init(&b, &c, &in) == 0);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
	struct fuzz_input in = {data, size};
	uint8_t kind, n;
	int ok = 1;

	start(size % 2 ? 3 : 0);
	while (ok && fuzz_event(&in, &kind, &n)) {
		switch (kind) {
		case FUZZ_START_W:
			if (a.proto.in_write)
				end_write(proto_on_write_start);
			else
				proto_on_write_start(&a.proto);
			fr.n = 0;
			break;
		case FUZZ_DATA:
			for (uint8_t i = 0; i < n; i++) {
				uint8_t byte = fuzz_byte(&in, &ok);

				if (!ok)
					break;
				proto_on_byte(&a.proto, byte);
				if (a.proto.in_write && fr.n < sizeof(fr.bytes))
					fr.bytes[fr.n++] = byte;
			}
			break;
		case FUZZ_START_R:
			if (a.proto.in_write)
				end_write(proto_on_read_start);
			else
				proto_on_read_start(&a.proto);
			break;
		case FUZZ_READ:
			for (uint8_t i = 0; i < n; i++)
				(void)proto_read_byte(&a.proto);
			break;
		case FUZZ_STOP:
			if (a.proto.in_write)
				end_write(n % 2 ? proto_on_stop : proto_on_restart);
			else if (n % 2)
				proto_on_stop(&a.proto);
			else
				proto_on_restart(&a.proto);
			break;
		case FUZZ_ABORT:
			if (a.proto.in_write)
				end_write(proto_on_abort);
			else
				proto_on_abort(&a.proto);
			break;
		case FUZZ_TICK:
			for (uint8_t i = 0; i < n; i++)
				tick();
			break;
		default: /* FUZZ_ENV */
			pl.shocks = fuzz_byte(&in, &ok);
			pl.flags = fuzz_byte(&in, &ok);
			break;
		}
	}
	return 0;
}
