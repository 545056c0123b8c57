/* The core's build options: each CONFIG_ feature is on unless the port's build turns it off (the
 * AVR's, where its CPU budget has no room: firmware/ports/avr/CMakeLists.txt). A feature that is
 * off reads 0 in VERSION's capabilities, and its messages are rejected as UNSUPPORTED. */
#ifndef ASSERV_FEATURE_SET_H
#define ASSERV_FEATURE_SET_H

#include "protocol_defs.h"

/* Position fixes, SET_FIX and FIX_INFO (fix.h). */
#ifndef CONFIG_FIX
#define CONFIG_FIX 1
#endif

/* The extensions of issue 31 a build carries (docs/protocol.md, "Match play"): 1, or 0 to leave
 * one out (the AVR's budget); its capability bit is then clear in VERSION and its messages are
 * rejected UNSUPPORTED. */
#ifndef CONFIG_MOTION_PAUSE
#define CONFIG_MOTION_PAUSE 1 /* PAUSE, RESUME, MOTION */
#endif
#ifndef CONFIG_MOTION_SPEED_SCALE
#define CONFIG_MOTION_SPEED_SCALE 1 /* SET_SPEED_SCALE */
#endif
#ifndef CONFIG_MOTION_QUEUE
#define CONFIG_MOTION_QUEUE 1 /* APPEND */
#endif
#ifndef CONFIG_MOTION_CORNERS
#define CONFIG_MOTION_CORNERS 1 /* PASS_THROUGH, SET_CORNER */
#endif

/* The pose and the radius kept across a reset that keeps the RAM (keep.h): the planner seals
 * its record every period. 0 (the AVR, whose budget has no room for the record's write): after
 * any reset but a power-on the pose is lost (motion orders refused until SET_NEW_POS) and the
 * order reported abandoned; the cause and the count are kept all the same, and VERSION's
 * KEEP_POSE bit is clear. */
#ifndef CONFIG_KEEP_POSE
#define CONFIG_KEEP_POSE 1
#endif

/* The quiet servo (issue 32): the PIDs' derivative through a low-pass of d_filter_ms (pid.h,
 * docs/control.md "PID"), and the raw derivative while braking after a shock (orders_raw_d()).
 * 0 (the AVR, whose budget has no room for the low-pass outside its PID kernel): the derivative
 * is the raw difference of two ticks' errors whatever control.d_filter_ms says, and VERSION's
 * QUIET_SERVO bit is clear. */
#ifndef CONFIG_QUIET_SERVO
#define CONFIG_QUIET_SERVO 1
#endif

/* Any of match play: without one, the motion module has nothing to follow or report. */
#define CONFIG_MOTION_ANY                                                                          \
	(CONFIG_MOTION_PAUSE || CONFIG_MOTION_SPEED_SCALE || CONFIG_MOTION_QUEUE ||                \
	 CONFIG_MOTION_CORNERS)

/* The capabilities of this build. */
#define CAP_BUILD                                                                                  \
	(CAP_ALL &                                                                                 \
	 ~((CONFIG_FIX ? 0u : CAP_FIX) | (CONFIG_MOTION_PAUSE ? 0u : CAP_PAUSE) |                  \
	   (CONFIG_MOTION_SPEED_SCALE ? 0u : CAP_SPEED_SCALE) |                                    \
	   (CONFIG_MOTION_QUEUE ? 0u : CAP_QUEUE) | (CONFIG_MOTION_CORNERS ? 0u : CAP_CORNERS) |   \
	   (CONFIG_QUIET_SERVO ? 0u : CAP_QUIET_SERVO)))

/* 1 when this build has the message's feature. */
static inline int feature_set_has(uint8_t designation)
{
	return CONFIG_FIX || (designation != PROTO_SET_FIX && designation != PROTO_FIX_INFO);
}

#endif
