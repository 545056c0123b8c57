/* The calibration record (see calib_store.h). */
#include "calib_store.h"

#define MAGIC0 CALIB_STORE_MAGIC0
#define MAGIC1 CALIB_STORE_MAGIC1
#define PPM_LIMIT 30000

/* Bitwise: 16 bytes once at start-up and once per calibration, so no table. */
uint16_t calib_store_crc16(const uint8_t *data, uint8_t n)
{
	uint16_t crc = 0xFFFFu;

	for (uint8_t i = 0; i < n; i++) {
		crc ^= (uint16_t)((uint16_t)data[i] << 8);
		for (uint8_t b = 0; b < 8; b++)
			crc = (crc & 0x8000u) ? (uint16_t)((crc << 1) ^ 0x1021u)
					      : (uint16_t)(crc << 1);
	}
	return crc;
}

static void put_u32(uint8_t *out, uint32_t v)
{
	out[0] = (uint8_t)(v >> 24);
	out[1] = (uint8_t)(v >> 16);
	out[2] = (uint8_t)(v >> 8);
	out[3] = (uint8_t)v;
}

static uint32_t get_u32(const uint8_t *in)
{
	return (uint32_t)in[0] << 24 | (uint32_t)in[1] << 16 | (uint32_t)in[2] << 8 | in[3];
}

void calib_store_encode(const struct board_calibration *cal, uint8_t gen,
			uint8_t out[CALIB_STORE_SIZE])
{
	uint16_t crc;

	out[0] = MAGIC0;
	out[1] = MAGIC1;
	out[2] = CALIB_STORE_VERSION;
	out[3] = gen;
	put_u32(&out[4], (uint32_t)cal->ratio_ppm);
	put_u32(&out[8], (uint32_t)cal->scale_ppm);
	out[12] = (uint8_t)(cal->track_10um >> 8);
	out[13] = (uint8_t)cal->track_10um;
	crc = calib_store_crc16(out, 14);
	out[14] = (uint8_t)(crc >> 8);
	out[15] = (uint8_t)crc;
}

static int all_bytes(const uint8_t *in, uint8_t v)
{
	for (uint8_t i = 0; i < CALIB_STORE_SIZE; i++)
		if (in[i] != v)
			return 0;
	return 1;
}

int calib_store_decode(const uint8_t in[CALIB_STORE_SIZE], struct board_calibration *cal)
{
	int32_t ratio, scale;

	if (all_bytes(in, 0xFFu) || all_bytes(in, 0x00u))
		return CALIB_STORE_BLANK;
	if (in[0] != MAGIC0 || in[1] != MAGIC1 ||
	    !(in[2] == CALIB_STORE_VERSION || (in[2] == CALIB_STORE_VERSION_1 && in[3] == 0)) ||
	    calib_store_crc16(in, 14) != (uint16_t)((uint16_t)in[14] << 8 | in[15]))
		return CALIB_STORE_CORRUPT;
	ratio = (int32_t)get_u32(&in[4]);
	scale = (int32_t)get_u32(&in[8]);
	if (ratio < -PPM_LIMIT || ratio > PPM_LIMIT || scale < -PPM_LIMIT || scale > PPM_LIMIT)
		return CALIB_STORE_RANGE;
	cal->ratio_ppm = ratio;
	cal->scale_ppm = scale;
	cal->track_10um = (uint16_t)((uint16_t)in[12] << 8 | in[13]);
	return 0;
}
