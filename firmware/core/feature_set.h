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

/* The capabilities of this build. */
#define CAP_BUILD (CAP_ALL & ~(CONFIG_FIX ? 0u : CAP_FIX))

/* 1 when this build has the message's feature. */
static inline int feature_set_has(uint8_t designation)
{
	return CONFIG_FIX || (designation != PROTO_SET_FIX && designation != PROTO_FIX_INFO);
}

#endif
