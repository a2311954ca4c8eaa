// The simulator's random draws (private to libs/sim).
#pragma once

#include <cstdint>
#include <random>

namespace rasterslam::sim::detail
{
/** Drawn from raw 32-bit outputs: std::uniform_real_distribution's algorithm is not fixed by the
 *  standard, this keeps a seed's world identical across standard libraries. */
class Rng
{
   public:
	explicit Rng(std::uint32_t seed) : gen_(seed) {}
	double uniform(double lo, double hi)
	{
		return lo + (hi - lo) * (static_cast<double>(gen_()) / 4294967296.0);
	}
	bool chance(double p) { return uniform(0, 1) < p; }
	/** A whole number in [lo, hi]. */
	int integer(int lo, int hi) { return lo + static_cast<int>(uniform(0, hi - lo + 1 - 1e-9)); }

   private:
	std::mt19937 gen_;
};
}  // namespace rasterslam::sim::detail
