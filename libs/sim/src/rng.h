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

inline std::uint64_t mix64(std::uint64_t x)
{
	x += 0x9E3779B97F4A7C15ull;
	x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
	x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
	return x ^ (x >> 31);
}

/** The key of one possible event: (world seed, kind of object, object, epoch). Events draw from
 *  their own keys, never from the generator that builds the world, so that the world of epoch
 *  0 does not depend on them. */
inline std::uint64_t eventKey(std::uint32_t seed, std::uint32_t stream, std::uint64_t id, int epoch)
{
	return mix64(mix64(mix64(seed ^ (std::uint64_t{stream} << 32)) ^ id) ^
	             static_cast<std::uint64_t>(epoch));
}
/** A draw in [0, 1) for that event. */
inline double eventDraw(std::uint32_t seed, std::uint32_t stream, std::uint64_t id, int epoch)
{
	return static_cast<double>(eventKey(seed, stream, id, epoch) >> 11) * 0x1.0p-53;
}
/** A generator for what the event makes (a new car's size, a new spot). */
inline Rng eventRng(std::uint32_t seed, std::uint32_t stream, std::uint64_t id, int epoch)
{
	return Rng(static_cast<std::uint32_t>(mix64(eventKey(seed, stream, id, epoch) + 1) >> 32));
}
}  // namespace rasterslam::sim::detail
