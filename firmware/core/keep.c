/* The record that survives a reset (keep.h). */
#include "keep.h"

/* Its words, summed with a rotation each so that two swapped or equal words do not cancel,
 * against a constant that an all-zero or all-one RAM does not give. */
uint32_t keep_check_word(const struct board_keep *k)
{
	const uint32_t w[] = {(uint32_t)k->x_um,
			      (uint32_t)k->y_um,
			      k->heading_turn32,
			      k->radius_um,
			      (uint32_t)k->u.tt,
			      (uint32_t)k->u.travel2_um,
			      (uint32_t)k->u.turn_um,
			      k->speed_um_s,
			      k->turn_um_s,
			      (uint32_t)k->spare0 | (uint32_t)k->resets << 8 |
				      (uint32_t)k->pose_lost << 16 | (uint32_t)k->spare << 24};
	uint32_t c = 0x6b656570u; /* "keep" */

	for (uint8_t i = 0; i < sizeof(w) / sizeof(w[0]); i++)
		c = ((c << 5) | (c >> 27)) + w[i];
	return c;
}

int keep_valid(const struct board_keep *k)
{
	return k->check == keep_check_word(k);
}

void keep_seal(struct board_keep *k)
{
	k->check = keep_check_word(k);
}
