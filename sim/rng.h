/* Seeded pseudo-random numbers for the simulator: xoshiro256** seeded through splitmix64.
 *
 * Algorithms from Blackman and Vigna, "Scrambled linear pseudorandom number generators" (2018)
 * and Steele, Lea and Flood, "Fast splittable pseudorandom number generators" (2014); written
 * here from their published descriptions. Same seed, same sequence, on every platform.
 */
#ifndef ASSERV_SIM_RNG_H
#define ASSERV_SIM_RNG_H

#include <stdint.h>

struct sim_rng {
	uint64_t s[4];
};

/* Seeds r from any 64-bit value (0 included). */
void sim_rng_seed(struct sim_rng *r, uint64_t seed);

/* Next 64 random bits. */
uint64_t sim_rng_next(struct sim_rng *r);

/* Uniform in [0, 1), 53 bits. */
double sim_rng_uniform(struct sim_rng *r);

/* Uniform in [lo, hi). */
double sim_rng_range(struct sim_rng *r, double lo, double hi);

/* Approximately standard normal (mean 0, variance 1): the sum of four uniforms (Irwin-Hall),
 * bounded at +/-3.46. Cheap (one draw, no libm) and plenty for encoder noise. */
double sim_rng_gauss(struct sim_rng *r);

#endif /* ASSERV_SIM_RNG_H */
