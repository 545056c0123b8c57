/* The odometry calibration as the board stores it (hal_nvm.h): a 16-byte record with a magic, a
 * version and a CRC, so that a blank, torn or foreign record is never installed.
 *
 *   bytes 0-1   magic 'a' 'c' (0x61 0x63)
 *   byte  2     CALIB_STORE_VERSION (1)
 *   byte  3     0 (reserved)
 *   bytes 4-7   ratio_ppm, int32, big-endian
 *   bytes 8-11  scale_ppm, int32, big-endian
 *   bytes 12-13 track_10um, uint16, big-endian
 *   bytes 14-15 CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF) of bytes 0-13, big-endian
 *
 * docs/calibration.md tells a team how the board keeps it. Pure functions: no HAL, no state. */
#ifndef ASSERV_CALIB_STORE_H
#define ASSERV_CALIB_STORE_H

#include <stdint.h>

#include "board.h"

#define CALIB_STORE_SIZE 16u /* [bytes] */
#define CALIB_STORE_VERSION 1u

/* calib_store_decode()'s refusals. */
#define CALIB_STORE_BLANK (-1)   /* every byte 0xFF (erased) or 0x00: nothing stored */
#define CALIB_STORE_CORRUPT (-2) /* a wrong magic, version, reserved byte or CRC */
#define CALIB_STORE_RANGE (-3)   /* a valid record whose ratio or scale is out of range */

/* The record of cal into out. Interrupt-safe: yes (no state). */
void calib_store_encode(const struct board_calibration *cal, uint8_t out[CALIB_STORE_SIZE]);

/* The calibration of a record: 0 and *cal, or a CALIB_STORE_* refusal and *cal untouched.
 * Ratio and scale must be within -30000..30000 ppm (board_set_calibration()'s range); the track
 * is checked by board_set_calibration(). Interrupt-safe: yes. */
int calib_store_decode(const uint8_t in[CALIB_STORE_SIZE], struct board_calibration *cal);

/* CRC-16/CCITT-FALSE of n bytes (check value of "123456789": 0x29B1). */
uint16_t calib_store_crc16(const uint8_t *data, uint8_t n);

#endif
