// The paper's map model ("Mapping", "Map Management"): local maps with their two labels
// (keyframes and time stamps), their points after local BA and their image, and the graph
// that links local maps.
#pragma once

#include <mrpt/serialization/CSerializable.h>

#include <cstdint>
#include <string>
#include <vector>

namespace rasterslam
{
/** A local map: keyframes grouped while the vehicle moves, refined together by local BA.
 *  Its frame is that of its anchor keyframe (the first), so its pose in the map is the
 *  anchor's pose, which the pose graph owns: a local map never holds a pose of its own. */
class LocalMap : public mrpt::serialization::CSerializable
{
	DEFINE_SERIALIZABLE(LocalMap, rasterslam)

   public:
	/** At most this many keyframes (the observer masks are 32 bits). */
	static constexpr std::size_t kMaxKeyframes = 32;

	uint64_t id = 0;  //!< unique across the sessions of a map
	uint32_t session = 0;
	/** Label 1: the keyframe ids, anchor first, in the order they were made. */
	std::vector<uint64_t> keyframes;
	/** Label 2: time stamps of creation (its first keyframe) and of the last update. */
	double createdStamp = 0, updatedStamp = 0;
	/** In the online local-map graph (false: kept in the offline store). */
	bool online = true;

	/** Map points in the anchor frame after local BA: a feature seen by several keyframes
	 *  is one point. One entry a point: 3 floats, 32 descriptor bytes, an observer mask
	 *  (bit k: seen by keyframes[k]). */
	std::vector<float> xyz;
	std::vector<uint8_t> descriptors;
	std::vector<uint32_t> observers;

	/** The local-map image (eq. 1 or the bird's-eye view of the map's points), PNG bytes
	 *  (it is only looked at, never matched, so it is kept compressed). */
	std::vector<uint8_t> imagePng;
	float imageResolution_m = 0;  //!< metres a pixel, 0 for the pinhole image
	float imageExtent_m = 0;      //!< the image covers +-extent around the anchor

	/** The local map's surfaces: its keyframes' whole scans (ground included) reduced to
	 *  one point a voxel, in the anchor frame, 3 coordinates a point in centimetres (16 bits:
	 *  within 327 m of the anchor). What a registration found on the features is refined on
	 *  (ICP); empty when the map manager keeps none (`surface_voxel_m: 0`) or the map was
	 *  written before version 1. */
	std::vector<int16_t> surfaceCm;
	std::size_t surfacePoints() const { return surfaceCm.size() / 3; }

	/** The place's polar contexts (places::PolarContext), one about each keyframe in the
	 *  order of `keyframes`: its non-ground points binned by range ring and azimuth sector,
	 *  each cell the height above the ground of its highest point in steps of
	 *  kContextStep_m (0: empty), ring-major. What the loop detector ranks places by beside
	 *  the image's words. Empty when the map manager makes none or the map was written before
	 *  version 2. */
	static constexpr float kContextStep_m = 0.05f;
	uint16_t contextRings = 0, contextSectors = 0;
	std::vector<uint8_t> contextCells;
	std::size_t contexts() const
	{
		const std::size_t n = std::size_t{contextRings} * contextSectors;
		return n == 0 ? 0 : contextCells.size() / n;
	}

	/** Local BA figures, for run reports. */
	uint32_t baTracks = 0;
	float baInitialRms_m = 0, baFinalRms_m = 0;

	uint64_t anchor() const { return keyframes.empty() ? 0 : keyframes.front(); }
	std::size_t points() const { return observers.size(); }
	/** Points or image present (an offline stub has neither; a map read from a file has both
	 *  whatever its online flag). */
	bool hasData() const { return !observers.empty() || !imagePng.empty(); }
	/** Index of a keyframe in `keyframes`, or -1. */
	int keyframeIndex(uint64_t kf) const;
	/** Bytes held in memory (for the memory budget). */
	std::size_t memoryBytes() const;
	bool operator==(const LocalMap& o) const;
};

/** Paper, "Map Management / Initialization": the graph of local maps. Sequential edges join
 *  local maps made one after the other, loop edges local maps joined by a loop closure,
 *  relocalization edges those joined when a lost or new session was located. Relative poses
 *  come from the anchors' poses, so edges carry none. */
class LocalMapGraph : public mrpt::serialization::CSerializable
{
	DEFINE_SERIALIZABLE(LocalMapGraph, rasterslam)

   public:
	enum class EdgeKind : uint8_t
	{
		Sequential = 0,
		Loop = 1,
		Relocalization = 2
	};
	struct Edge
	{
		uint64_t from = 0, to = 0;
		EdgeKind kind = EdgeKind::Sequential;
		double stamp = 0;  //!< when it was made
		bool operator==(const Edge& o) const
		{
			return from == o.from && to == o.to && kind == o.kind && stamp == o.stamp;
		}
	};
	std::vector<Edge> edges;

	void add(uint64_t from, uint64_t to, EdgeKind kind, double stamp);
	std::size_t count(EdgeKind kind) const;
	bool operator==(const LocalMapGraph& o) const { return edges == o.edges; }
};
const char* toString(LocalMapGraph::EdgeKind k);

}  // namespace rasterslam
