/* The odometry calibration as the board stores it (hal_nvm.h): a 16-byte record with a magic, a
 * version and a CRC, so that a blank, torn or foreign record is never installed, and a
 * generation, so that the newest of the records a port keeps is known (nvm_bytes.h, stm32_nvm.h).
 *
 *   bytes 0-1   magic 'a' 'c' (0x61 0x63)
 *   byte  2     CALIB_STORE_VERSION (2)
 *   byte  3     generation, 0..255, compared as a serial number (calib_store_newer())
 *   bytes 4-7   ratio_ppm, int32, big-endian
 *   bytes 8-11  scale_ppm, int32, big-endian
 *   bytes 12-13 track_10um, uint16, big-endian
 *   bytes 14-15 CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF) of bytes 0-13, big-endian
 *
 * Version 1 (the boards of before the generation) had byte 3 at 0: such a record still decodes,
 * as generation 0, so that a board keeps its calibration across the update. docs/calibration.md
 * tells a team how the board keeps it. Pure functions: no HAL, no state. */
#ifndef ASSERV_CALIB_STORE_H
#define ASSERV_CALIB_STORE_H

#include <stdint.h>

#include "board.h"

#define CALIB_STORE_SIZE 16u     /* [bytes] */
#define CALIB_STORE_MAGIC0 0x61u /* byte 0, 'a' */
#define CALIB_STORE_MAGIC1 0x63u /* byte 1, 'c' */
#define CALIB_STORE_VERSION 2u
#define CALIB_STORE_VERSION_1 1u /* still decoded: byte 3 then 0 */

/* calib_store_decode()'s refusals. */
#define CALIB_STORE_BLANK (-1)   /* every byte 0xFF (erased) or 0x00: nothing stored */
#define CALIB_STORE_CORRUPT (-2) /* a wrong magic, version or CRC (or version 1, byte 3 not 0) */
#define CALIB_STORE_RANGE (-3)   /* a valid record whose ratio or scale is out of range */

/* The record of cal, of generation gen, into out (version CALIB_STORE_VERSION). Interrupt-safe:
 * yes (no state). */
void calib_store_encode(const struct board_calibration *cal, uint8_t gen,
			uint8_t out[CALIB_STORE_SIZE]);

/* The calibration of a record: 0 and *cal, or a CALIB_STORE_* refusal and *cal untouched.
 * Ratio and scale must be within -30000..30000 ppm (board_set_calibration()'s range); the track
 * is checked by board_set_calibration(). Interrupt-safe: yes. */
int calib_store_decode(const uint8_t in[CALIB_STORE_SIZE], struct board_calibration *cal);

/* The generation of a record calib_store_decode() accepted (a version-1 record's: 0). */
static inline uint8_t calib_store_generation(const uint8_t in[CALIB_STORE_SIZE])
{
	return in[3];
}

/* 1 when generation a is newer than b: a - b is 1..127 modulo 256 (RFC 1982's serial number
 * arithmetic). A port keeps at most a few generations at once, so a wrap never misorders
 * them. */
static inline uint8_t calib_store_newer(uint8_t a, uint8_t b)
{
	return (uint8_t)(a - b) - 1u < 127u;
}

/* 1 when a and b are the same calibration. Inline: the main loop asks it at every pass. */
static inline uint8_t calib_store_same(const struct board_calibration *a,
				       const struct board_calibration *b)
{
	return a->ratio_ppm == b->ratio_ppm && a->scale_ppm == b->scale_ppm &&
	       a->track_10um == b->track_10um;
}

/* CRC-16/CCITT-FALSE of n bytes (check value of "123456789": 0x29B1). */
uint16_t calib_store_crc16(const uint8_t *data, uint8_t n);

#endif
