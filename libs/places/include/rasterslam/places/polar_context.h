// A place's polar context: the points of a scan or a local map (ground removed, as the
// elevation image keeps them) binned by range ring and azimuth sector around the frame's
// origin, each cell holding the height above the ground of its highest point. The same
// place seen turned shifts the sectors and leaves the rings' occupancy unchanged, so the
// comparison is free of the pixel grid that makes ORB words change when a place is seen
// turned by an angle that is not a multiple of 90 degrees (the idea of Kim and Kim's Scan
// Context, IROS 2018; written here from the paper's description).
#pragma once

#include <rasterslam/core/types.h>

#include <cstdint>
#include <vector>

namespace rasterslam::places
{
struct PolarParams
{
	/** 10 rings of 6 m: on the simulated towns' local maps 20 rings of 3 m (Scan Context's
	 *  choice for single scans) ranked the true place among the first 5 for 0.66 of the
	 *  queries, 10 rings for 0.83 (8 towns, 80 queries; rasterslam-bench-places --polar). */
	int rings = 10;
	int sectors = 60;
	double maxRange_m = 60.0;
	/** Added to a point's z to give its height above the ground (points in a sensor frame:
	 *  the sensor's height). Heights below zero count as zero (the cell stays empty). */
	double heightOffset_m = 1.73;
	/** Contexts compared in full per query, chosen by the rings' occupancy. */
	int ringCandidates = 250;
	/** Sector shifts compared in full per candidate, chosen by the sectors' occupancy
	 *  (each with its two neighbours). */
	int shiftCandidates = 3;
};

struct PolarContext
{
	int rings = 0, sectors = 0;
	std::vector<float> cells;    //!< rings x sectors, row-major by ring; 0: empty
	std::vector<float> ringKey;  //!< share of each ring's sectors that are occupied
	std::vector<int> sectorKey;  //!< number of each sector's rings that are occupied
	/** sectorKey in bytes, twice over, then its first sectors again up to a whole block of 16
	 *  past the second copy: the sliding windows comparePolar() compares. Empty when a count
	 *  does not fit a byte (more than 255 rings). Made with the keys (polarContext(),
	 *  polarContextOfCells()): a sectorKey changed by hand would not be seen. */
	std::vector<uint8_t> sectorBytes;
	/** Sector-major: each sector's ring column scaled to unit length (all 0 when empty), what
	 *  comparePolar() takes the cosines of. */
	std::vector<float> columns;
	std::size_t index(int r, int s) const
	{
		return static_cast<std::size_t>(r) * static_cast<std::size_t>(sectors) +
		       static_cast<std::size_t>(s);
	}
	float& at(int r, int s) { return cells[index(r, s)]; }
	float at(int r, int s) const { return cells[index(r, s)]; }
};

/** The polar context of `pts` (x forward, y left, z up, about the frame's origin). */
PolarContext polarContext(const std::vector<PointXYZI>& pts, const PolarParams& p = {});

/** The cells of `c` in steps of `step_m` (rounded, at most 255 steps; an occupied cell is
 *  at least 1): how a map keeps a context (LocalMap::contextCells). */
std::vector<uint8_t> quantizedCells(const PolarContext& c, float step_m);

/** The context of cells kept as quantizedCells() makes them (rings x sectors of them). */
PolarContext polarContextOfCells(int rings, int sectors, const uint8_t* cells, float step_m);

struct PolarMatch
{
	/** Mean over the sectors occupied in both of 1 - cosine of their ring columns, at the
	 *  best shift; in [0, 1] (0: the same), 1 when no sector is occupied in both. */
	double distance = 1.0;
	/** Sectors that `b` is turned against `a` at the best shift: a's sector s matches b's
	 *  sector (s + shift) mod sectors. */
	int shift = 0;
};

/** For each shift of b's sectors (a's sector s against b's (s + shift) mod sectors), the L1
 *  distance of the two sector keys: how comparePolar() chooses the shifts it compares in
 *  full. Both must have the same dimensions. */
std::vector<int> sectorKeyDistances(const PolarContext& a, const PolarContext& b);

/** The two contexts compared at every sector shift that the sector keys rank among the
 *  best `shiftCandidates` (and their neighbours); both must have the same dimensions. */
PolarMatch comparePolar(const PolarContext& a, const PolarContext& b, int shiftCandidates = 3);

/** Places' polar contexts, queried by ring-key distance then the full comparison. */
class PolarIndex
{
   public:
	explicit PolarIndex(const PolarParams& p = {}) : p_(p) {}
	/** Adds a place; returns its id (0, 1, ... in the order of insertion; never reused). */
	std::size_t add(PolarContext ctx);
	/** Removes a place (its context's memory is freed; its ring key, 4 bytes a ring, stays
	 *  among the others); false when there is none of that id. */
	bool remove(std::size_t id);
	bool contains(std::size_t id) const { return id < live_.size() && live_[id]; }
	/** A place's context; null when there is none of that id. */
	const PolarContext* context(std::size_t id) const
	{
		return contains(id) ? &places_[id] : nullptr;
	}
	/** Places held (removed ones not counted). */
	std::size_t size() const { return live_count_; }
	const PolarParams& params() const { return p_; }

	struct Result
	{
		std::size_t id = 0;
		PolarMatch match;
	};
	/** The best `maxResults` places by distance (ascending; ties by id) among the
	 *  `ringCandidates` closest by ring key; each match is comparePolar(q, place). */
	std::vector<Result> query(const PolarContext& q, std::size_t maxResults) const;

   private:
	PolarParams p_;
	std::vector<PolarContext> places_;
	std::vector<char> live_;  //!< 0: removed
	/** Every place's ring key (p_.rings each, in the order of ids; removed ones too). */
	std::vector<float> ringKeys_;
	std::size_t live_count_ = 0;
};

}  // namespace rasterslam::places
