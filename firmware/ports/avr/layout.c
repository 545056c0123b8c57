/* The layout record of avr_layout.h, in flash. The linker keeps it (-Wl,--undefined=avr_layout)
 * although nothing in the firmware reads it. */
#include <stddef.h>

#include <avr/pgmspace.h>

#include "avr_layout.h"
#include "board.h"

#define AT(member) ((uint16_t)offsetof(struct board, member))

const struct avr_layout avr_layout PROGMEM = {
	.magic = AVR_LAYOUT_MAGIC,
	.size = sizeof(struct avr_layout),
	.board_size = sizeof(struct board),
	.tick_hz = AT(cfg.tick_hz),
	.slow_shift = AT(cfg.slow_shift),
	.tick = AT(servo.tick),
	.slow_due = AT(mailbox.slow_due),
	.slow_overruns = AT(servo.slow_overruns),
	.since_snapshot = AT(servo.since_snapshot),
	.planner_ticks = AT(cfg.planner_ticks),
	.odo_x_um = AT(planner.position.x_um),
	.odo_y_um = AT(planner.position.y_um),
	.odo_x_frac = AT(planner.position.x_frac),
	.odo_y_frac = AT(planner.position.y_frac),
	.odo_heading = AT(servo.counter.heading_turn32),
	.odo_left_count = AT(servo.counter.left_count),
	.odo_right_count = AT(servo.counter.right_count),
	.duty = AT(servo.last_out.duty_q15),
	.proto_selected = AT(proto.selected),
	.proto_head = AT(proto.head),
	.proto_tail = AT(proto.tail),
	.proto_queue = AT(proto.queue),
	.proto_snap = AT(proto.snap),
	.proto_snap_index = AT(proto.snap_index),
	.msg_size = sizeof(struct proto_msg),
	.msg_designation = offsetof(struct proto_msg, designation),
	.msg_n_args = offsetof(struct proto_msg, n_args),
	.msg_arg = offsetof(struct proto_msg, arg),
	.snap_size = sizeof(struct proto_snapshot),
	.snap_x_mm = offsetof(struct proto_snapshot, x_mm),
	.snap_y_mm = offsetof(struct proto_snapshot, y_mm),
	.snap_angle_2deg = offsetof(struct proto_snapshot, angle_2deg),
	.snap_radius_mm = offsetof(struct proto_snapshot, radius_mm),
	.snap_status = offsetof(struct proto_snapshot, status),
	.snap_sensors = offsetof(struct proto_snapshot, sensors),
	.odo_left_factor = AT(servo.counter.cfg.left_um_per_count_q16),
	.odo_right_factor = AT(servo.counter.cfg.right_um_per_count_q16),
	.odo_track = AT(servo.counter.cfg.track_um),
	.calibrated = AT(planner.calibrated),
	.calibration = AT(planner.calibration),
};
