// `rasterslam map merge` and `map prune`. Merge: two maps built separately become one (paper, "Map
// Management": sessions that land in one map). The loaded map stays where it is; the other is
// located in it local map by local map, and only a transform that several of them agree on is used.
#include <rasterslam/core/engine.h>

#include <algorithm>
#include <cmath>
#include <set>
#include <stdexcept>
#include <tuple>

#include "information.h"

namespace rasterslam
{
MergeReport Engine::mergeMap(const std::string& dir)
{
	if (!mapManager_ || !loopDetector_ || !optimizer_)
		throw ConfigError(source_ +
		                  ": merging maps needs a map_manager, a loop_detector and an optimizer");
	const Map other = rasterslam::loadMap(dir);
	const Map& map = mapManager_->map();
	if (map.localMaps.empty())
		throw std::runtime_error("the first map has no local maps");
	MergeReport rep;
	rep.localMaps = other.localMaps.size();
	PoseView here;
	here.prior = &map.priorPoses;

	// Each keyframe of the other map (the points of a local map it saw), located with no
	// prior: where it puts the other map's frame. Keyframes, not local maps, so that a small
	// map still gives several independent hits. A local map none of whose keyframes is found
	// is located whole (all its points; its surface refines the pose, and searches it when
	// the detector's surface search is on): another sensor in a changed town matches too few
	// features a keyframe (session 10 of benchmark-sessions.sh against session 1's map: 2 of
	// 59 keyframes, then 3 of the 10 local maps left, whole).
	struct Hit
	{
		uint64_t theirs = 0;    //!< local map of the other map
		uint64_t keyframe = 0;  //!< keyframe of the other map (a local map's anchor: whole)
		RelocalizationResult rl;
		mrpt::poses::CPose3D T_this_other;
	};
	std::vector<Hit> hits;
	std::set<uint64_t> tried, found;
	const auto log = [&](const std::string& what, const RelocalizationResult& rl)
	{
		if (rl.found)
			MRPT_LOG_DEBUG_STREAM(what << " of " << dir << " found at local map " << rl.localMap
			                           << " (" << rl.inliers << " inliers)");
		else
			MRPT_LOG_DEBUG_STREAM(what << " of " << dir << " not located: " << rl.reason
			                           << " (score " << rl.score << ", " << rl.inliers
			                           << " inliers)");
	};
	for (const auto& [id, stub] : other.localMaps)
	{
		const auto lm = other.data(id);
		const auto anchorPose = other.priorPoses.at(lm->anchor());
		const auto T_this_other = [&anchorPose](const RelocalizationResult& rl)
		{ return rl.pose + (mrpt::poses::CPose3D() - anchorPose); };
		for (std::size_t k = 0; k < lm->keyframes.size(); k++)
		{
			if (!tried.insert(lm->keyframes[k]).second)
				continue;  // shared with the previous local map
			const auto rl = loopDetector_->locate(*lm, map, here, static_cast<int>(k));
			log("keyframe " + std::to_string(lm->keyframes[k]), rl);
			if (!rl.found)
				continue;
			hits.push_back({id, lm->keyframes[k], rl, T_this_other(rl)});
			found.insert(lm->keyframes[k]);
		}
		// Whole only where none of its keyframes (those shared with the local map before it
		// included) is in a hit already, a keyframe's or a whole local map's: no keyframe's
		// features are counted twice.
		if (std::none_of(lm->keyframes.begin(), lm->keyframes.end(),
		                 [&found](uint64_t k) { return found.count(k) > 0; }))
		{
			rep.localMapsWhole++;
			const auto rl = loopDetector_->locate(*lm, map, here, -1);
			log("local map " + std::to_string(id) + " (whole)", rl);
			if (rl.found)
			{
				hits.push_back({id, lm->anchor(), rl, T_this_other(rl)});
				found.insert(lm->keyframes.begin(), lm->keyframes.end());
				rep.locatedWhole++;
			}
		}
	}
	rep.keyframesTried = tried.size();
	rep.located = hits.size() - rep.locatedWhole;
	// The hit that the most others agree with (compared where each other hit is: a heading
	// difference counts as the offset it makes there).
	std::vector<std::size_t> best;
	for (std::size_t i = 0; i < hits.size(); i++)
	{
		std::vector<std::size_t> agree;
		for (std::size_t j = 0; j < hits.size(); j++)
		{
			const auto at = other.priorPoses.at(hits[j].keyframe);
			const auto d = (hits[i].T_this_other + at) - (hits[j].T_this_other + at);
			if (anchorsAgree(d))
				agree.push_back(j);
		}
		if (agree.size() > best.size())
			best = agree;
	}
	rep.agreeing = best.size();
	if (best.size() < static_cast<std::size_t>(anchorMinAgreeing_))
		throw std::runtime_error(
		    "no overlap found between the maps: " + std::to_string(rep.located) + " of " +
		    std::to_string(tried.size()) + " keyframes of '" + dir + "' were located (and " +
		    std::to_string(rep.locatedWhole) + " of " + std::to_string(rep.localMapsWhole) +
		    " local maps whole, none of whose keyframes was in a hit), " +
		    std::to_string(best.size()) + " agree on one place, " +
		    std::to_string(anchorMinAgreeing_) + " needed (engine.anchor_min_agreeing)");
	rep.T_this_other = hits[best.front()].T_this_other;

	// The pose graph: the loaded map's keyframes that a hit names (fixed), the other map's
	// keyframes (numbered after the loaded map's), consecutive ones tied by their relative
	// pose in the other map, and each agreeing hit as a relocalization edge (robust loss).
	mrpt::graphs::CNetworkOfPoses3DInf g;
	const uint64_t offset = map.nextKeyframeId();
	std::set<mrpt::graphs::TNodeID> fixed;
	EdgeSet uncertain;
	for (const auto& [id, p] : other.priorPoses)
		g.nodes[offset + id] = rep.T_this_other + p;
	const auto seqInfo = diagonalInformation(0.05, 0.5);  // the other map's own estimate: a few cm
	// A hit: 0.1 m and 0.5 deg. A relocalization's rotation is good to about 0.2 deg (median
	// on the rendered KITTI revisits), and it is the rotation that a few hits on one stretch
	// of B must give (0.1 rad before: sessions 4 and 10 of benchmark-sessions.sh merged into
	// session 1's map 0.82 and 1.04 m off, now 0.58 and 0.39).
	const auto hitInfo = diagonalInformation(0.1, 0.5);
	std::optional<uint64_t> prev;
	for (const auto& [id, k] : other.keyframes)
	{
		if (prev)
			g.insertEdge(offset + *prev, offset + id,
			             mrpt::poses::CPose3DPDFGaussianInf(
			                 other.priorPoses.at(id) - other.priorPoses.at(*prev), seqInfo));
		prev = id;
	}
	std::set<std::pair<uint64_t, uint64_t>> links;
	for (const auto i : best)
	{
		const auto& h = hits[i];
		g.nodes[h.rl.keyframe] = h.rl.keyframePose;
		fixed.insert(h.rl.keyframe);
		// The hit placed the local map's anchor; the edge goes to the keyframe it was made from.
		const auto anchor = other.localMaps.at(h.theirs)->anchor();
		const auto T_this_kf =
		    h.rl.pose + (other.priorPoses.at(h.keyframe) - other.priorPoses.at(anchor));
		g.insertEdge(h.rl.keyframe, offset + h.keyframe,
		             mrpt::poses::CPose3DPDFGaussianInf(T_this_kf - h.rl.keyframePose, hitInfo));
		uncertain.insert({h.rl.keyframe, offset + h.keyframe});
		links.emplace(h.rl.localMap, h.theirs);
	}
	g.root = *fixed.begin();
	const auto before = g.nodes;
	rep.optimization = optimizer_->optimize(g, uncertain, fixed);
	std::map<uint64_t, mrpt::poses::CPose3D> poses;
	for (const auto& [id, p] : other.priorPoses)
	{
		poses[id] = g.nodes.at(offset + id);
		rep.maxCorrection_m =
		    std::max(rep.maxCorrection_m, poses[id].distanceTo(before.at(offset + id)));
	}

	// B's local maps enter the place index, but not those B had itself retired (replaced on
	// a revisit by a newer one of the same place).
	const auto inB = loopDetector_->indexedIn(other);
	const auto added = mapManager_->addMap(other, poses, {links.begin(), links.end()});
	std::map<uint64_t, uint64_t> original;
	for (const auto& [b, here] : added.localMapIds)
		original[here] = b;
	for (const auto& fin : added.localMaps)
		if (!inB || inB->count(original.at(fin.localMap)))
			// Whole (its polar contexts; it went to the store as it came, whence it is read
			// again: a damaged file stops the merge, naming it, before anything is written).
			loopDetector_->index(*mapManager_->map().data(fin.localMap), fin.imageDescriptors);
	rep.sessions = mapManager_->map().sessions;
	rep.keyframes = mapManager_->map().keyframes.size();
	return rep;
}

PruneReport Engine::pruneMap(const PruneOptions& opts)
{
	if (!mapManager_)
		throw ConfigError(source_ + ": pruning a map needs a map_manager");
	const Map& map = mapManager_->map();
	if (!map.placeIndex.empty() && !loopDetector_)
		throw ConfigError(source_ +
		                  ": the map has a place index and the config no loop_detector to keep it "
		                  "up to date: use the "
		                  "config the map was made with (e.g. slam.yaml)");
	PruneReport rep;
	rep.localMaps = map.localMaps.size();
	// Newest first: a session made later (its record's time; a merged map's sessions keep
	// theirs, whatever their ids), then a later update.
	auto made = [&](uint32_t s)
	{
		const auto it = map.sessionRecords.find(s);
		return it == map.sessionRecords.end() ? std::string() : it->second.startedAt;
	};
	std::vector<uint64_t> ids;
	for (const auto& [id, lm] : map.localMaps)
		ids.push_back(id);
	std::sort(ids.begin(), ids.end(),
	          [&](uint64_t a, uint64_t b)
	          {
		          const auto &x = *map.localMaps.at(a), &y = *map.localMaps.at(b);
		          return std::make_tuple(made(x.session), x.session, x.updatedStamp, x.id) >
		                 std::make_tuple(made(y.session), y.session, y.updatedStamp, y.id);
	          });
	// A place: local maps whose anchors lie within place_radius_m of each other. Going from
	// the newest, a local map is surplus where `keepPerPlace` kept ones are that near already.
	std::vector<std::pair<uint64_t, mrpt::poses::CPose3D>> kept;
	std::set<uint64_t> drop;
	for (const auto id : ids)
	{
		const auto& lm = *map.localMaps.at(id);
		const auto at = map.priorPoses.at(lm.anchor());
		std::size_t near = 0;
		for (const auto& [k, p] : kept)
			near += p.distanceTo(at) < opts.placeRadius_m;
		if (near == 0)
			++rep.places;
		const bool old = opts.before && lm.updatedStamp < *opts.before;
		const bool surplus = opts.keepPerPlace && near >= *opts.keepPerPlace;
		const bool eligible = !map.onlineWhenSaved.count(id) && (opts.before || opts.keepPerPlace);
		if (eligible && (old || !opts.before) && (surplus || !opts.keepPerPlace))
			drop.insert(id);
		else
			kept.emplace_back(id, at);
	}
	if (!drop.empty() && drop.size() == map.localMaps.size())
		throw std::runtime_error("every local map of the map would be dropped: nothing is changed");
	rep.dropped.assign(drop.begin(), drop.end());
	if (opts.dryRun || drop.empty())
		return rep;
	// Kept local maps that a dropped one replaced on a revisit: their place-index entry had
	// gone to it, so they take it back (from their image), or the place could not be found.
	std::set<uint64_t> replacedByDropped;
	for (const auto& e : map.graph.edges)
		if (e.kind == LocalMapGraph::EdgeKind::Loop && drop.count(e.to) && !drop.count(e.from))
			replacedByDropped.insert(e.from);
	for (const auto id : drop)
		if (loopDetector_)
			loopDetector_->forget(id);
	rep.keyframesDropped = mapManager_->removeLocalMaps(drop);
	if (loopDetector_)
		for (const auto id : replacedByDropped)
			if (!loopDetector_->indexes(id))
			{
				// Whole (its polar contexts), read from the store when offline.
				loopDetector_->index(*mapManager_->map().data(id),
				                     mapManager_->imageDescriptors(id));
				++rep.reindexed;
			}
	return rep;
}

}  // namespace rasterslam
