/* Seeded pseudo-random numbers for the simulator (see rng.h). */
#include "rng.h"

static uint64_t splitmix64(uint64_t *state)
{
	uint64_t z = (*state += 0x9e3779b97f4a7c15u);

	z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9u;
	z = (z ^ (z >> 27)) * 0x94d049bb133111ebu;
	return z ^ (z >> 31);
}

static uint64_t rotl(uint64_t x, int k)
{
	return (x << k) | (x >> (64 - k));
}

void sim_rng_seed(struct sim_rng *r, uint64_t seed)
{
	uint64_t st = seed;
	int i;

	/* splitmix64 never yields four zero words in a row, so the state is never all zero */
	for (i = 0; i < 4; i++)
		r->s[i] = splitmix64(&st);
}

uint64_t sim_rng_next(struct sim_rng *r)
{
	uint64_t *s = r->s;
	uint64_t result = rotl(s[1] * 5, 7) * 9;
	uint64_t t = s[1] << 17;

	s[2] ^= s[0];
	s[3] ^= s[1];
	s[1] ^= s[2];
	s[0] ^= s[3];
	s[2] ^= t;
	s[3] = rotl(s[3], 45);
	return result;
}

double sim_rng_uniform(struct sim_rng *r)
{
	return (double)(sim_rng_next(r) >> 11) * (1.0 / 9007199254740992.0);
}

double sim_rng_range(struct sim_rng *r, double lo, double hi)
{
	return lo + (hi - lo) * sim_rng_uniform(r);
}

double sim_rng_gauss(struct sim_rng *r)
{
	uint64_t v = sim_rng_next(r);
	uint32_t sum = (uint32_t)(v & 0xffff) + (uint32_t)((v >> 16) & 0xffff) +
		       (uint32_t)((v >> 32) & 0xffff) + (uint32_t)(v >> 48);

	/* each 16-bit word + 0.5 over 2^16 is uniform in (0, 1): mean 1/2, variance 1/12 */
	return ((double)sum + 2.0 - 131072.0) * (1.7320508075688772 / 65536.0);
}
