/* The uncertainty's configuration, odometry model and rate in one line, as the tests state
 * them (uncertainty.h keeps them apart: the model is state that a calibration replaces). */
#ifndef ASSERV_TEST_UNCERTAINTY_SETUP_H
#define ASSERV_TEST_UNCERTAINTY_SETUP_H

#include "uncertainty.h"

struct uncertainty_setup {
	uint32_t noise_left_mm2_per_m_q16;
	uint32_t noise_right_mm2_per_m_q16;
	uint32_t track_um;
	uint32_t ratio_error_ppm;
	uint32_t track_error_um;
	uint32_t scale_error_ppm;
	uint16_t k_q8;
	uint16_t batch_ms;
	uint16_t rate_hz;
};

static inline struct uncertainty_model uncertainty_setup_model(const struct uncertainty_setup *s)
{
	struct uncertainty_model m = {s->track_um, s->ratio_error_ppm, s->track_error_um,
				      s->scale_error_ppm};

	return m;
}

static inline int uncertainty_setup_init(struct uncertainty *u, const struct uncertainty_setup *s)
{
	struct uncertainty_config c = {s->noise_left_mm2_per_m_q16, s->noise_right_mm2_per_m_q16,
				       s->k_q8, s->batch_ms};
	struct uncertainty_model m = uncertainty_setup_model(s);

	return uncertainty_init(u, &c, s->rate_hz, &m);
}

static inline int uncertainty_setup_set(struct uncertainty *u, const struct uncertainty_setup *s)
{
	struct uncertainty_model m = uncertainty_setup_model(s);

	return uncertainty_set_model(u, &m);
}

#endif
