// The paper's mapping thread ("Mapping", "Map Management"): keyframes grow a local map up to
// a size threshold; a finished local map is refined by local BA (eqs. 3-4), its points are
// rasterized into the local-map image (eq. 1 / bird's-eye view) and its image's ORB words go
// to the place index. Consecutive local maps share a keyframe, so the transition is smooth.
#include <mrpt/core/initializer.h>
#include <rasterslam/core/plugin.h>
#include <rasterslam/core/pose_conversions.h>
#include <rasterslam/features/icp.h>
#include <rasterslam/features/orb_extractor.h>
#include <rasterslam/map/registration.h>
#include <rasterslam/mapping/local_ba.h>
#include <rasterslam/places/polar_context.h>
#include <rasterslam/raster/elevation_image.h>
#include <signal.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cmath>
#include <deque>
#include <filesystem>
#include <opencv2/imgcodecs.hpp>

namespace rasterslam
{
class LocalMapManager : public MapManager
{
	DEFINE_MRPT_OBJECT(LocalMapManager, rasterslam)

   public:
	MappingUpdate addKeyframe(const KeyframeInfo& kf, const Scan& scan, const RasterFrame* raster,
	                          const PoseView& poses) override;
	MappingUpdate finish(const PoseView& poses) override;
	void loopAccepted(uint64_t fromKf, uint64_t toKf, double stamp) override;
	const Map& map() const override { return map_; }
	void describeSession(const SessionRecord& session) override;
	Added addMap(const Map& other, const std::map<uint64_t, mrpt::poses::CPose3D>& poses,
	             const std::vector<std::pair<uint64_t, uint64_t>>& links) override;
	void loadMap(const std::string& dir) override;
	std::size_t removeLocalMaps(const std::set<uint64_t>& localMaps) override;
	std::vector<uint8_t> imageDescriptors(uint64_t localMap) override;
	PlaceContext placeContextOf(const Scan& scan, const RasterFrame& raster) const override;
	~LocalMapManager() override;
	void saveMap(const std::string& dir, const PoseView& poses, const std::string& placeIndexClass,
	             const std::vector<uint8_t>& placeIndex) override;

   protected:
	void initializeImpl(ParamReader& p) override;

   private:
	/** Finishes the open local map; `continues`: the next one starts from its last keyframe. */
	void finishOpen(const PoseView& poses, MappingUpdate& up, bool continues);
	/** The keyframes' surfaces in the anchor frame (poses T), one point a voxel, in cm. */
	std::vector<int16_t> surfaceOf(const std::vector<uint64_t>& ids,
	                               const std::vector<Eigen::Isometry3d>& T) const;
	/** Drops what a keyframe no longer needs once all its local maps are finished. */
	void release(uint64_t kf);
	/** Paper, "Map Management / Culling": local maps farther along the route than
	 *  cull_distance_m, and the oldest past max_online_maps, leave the online graph. */
	void cull();
	/** Moves a local map to the offline store, leaving a stub with its labels. */
	void goOffline(uint64_t localMap, const char* why);
	LocalMapStore& store();
	/** ORB descriptors (32 bytes each) of a local-map image, for the place index. */
	std::vector<uint8_t> wordsOfImage(const cv::Mat& image);
	/** The same from a local map's stored PNG. */
	std::vector<uint8_t> wordsOf(const LocalMap& lm);
	/** place_query_keyframes > 0: into up.placeQuery the descriptors of the image of the last
	 *  keyframes' clouds (the local map being built around keyframe `kf`) in kf's frame,
	 *  rasterized as a local-map image is: the loop detector's query, image against image;
	 *  into up.placeQueryTurns those of the same points rasterized turned (place_query_turns). */
	void makePlaceQuery(uint64_t kf, const PoseView& poses, MappingUpdate& up);
	/** polar_contexts: the polar context of `pts` (non-ground points about a keyframe, in
	 *  its frame) as a map keeps it (LocalMap::contextCells). */
	std::vector<uint8_t> contextCells(const std::vector<PointXYZI>& pts) const;

	// parameters
	int keyframesPerMap_ = 5;
	int placeQueryKeyframes_ = 0;  //!< keyframes in the loop query's image (0: no image)
	int placeQueryTurns_ = 1;      //!< the query's image also turned by k * 90 / this (k >= 1)
	/** Polar contexts of each local map about its keyframes, and of the place query about its
	 *  keyframe, for the loop detector's second ranking. */
	bool polarContexts_ = false;
	places::PolarParams polar_;
	double maxExtent_m_ = 40;
	bool overlap_ = true;
	bool localBa_ = false;
	/** Map points: one per observation (each keeps its descriptor) or one per track. */
	bool mapPointsPerFeature_ = true;
	mapping::LocalBaParams ba_;
	raster::RasterParams mapRaster_;
	features::OrbParams mapOrb_;
	double cullDistance_m_ = 300;
	bool cullOnLoop_ = true;
	bool indexReplaced_ = false;  //!< local maps replaced on a revisit keep their place-index entry
	int maxOnlineMaps_ = 64;
	/** Surfaces kept with each local map for refining registrations (0: none). */
	double surfaceVoxel_m_ = 0;
	double surfaceRange_m_ = 40;
	std::string offlineDir_;
	bool ownOfflineDir_ = false;  //!< a temporary folder of this run, removed at the end

	// state
	Map map_;
	uint32_t session_ = 0;
	std::vector<uint64_t> open_;    //!< keyframes of the local map being built
	bool openSharesFirst_ = false;  //!< open_[0] is the last keyframe of the previous local map
	std::optional<uint64_t>
	    lastLocalMap_;  //!< the previous local map, when the open one continues it
	std::map<uint64_t, std::vector<PointXYZI>> clouds_;  //!< non-ground points of open keyframes
	/** place_query_keyframes > 0: the latest keyframes' non-ground points, oldest first. */
	std::deque<std::pair<uint64_t, std::vector<PointXYZI>>> queryWindow_;
	/** surface_voxel_m > 0: each open keyframe's scan reduced to one point a voxel. */
	std::map<uint64_t, std::vector<Eigen::Vector3f>> surfaces_;
	std::vector<uint64_t>
	    pendingLoops_;  //!< local maps a keyframe of the open map closed a loop with
	std::vector<uint64_t>
	    pendingRelocs_;  //!< local maps a keyframe of the open map was relocalized in
	std::unique_ptr<features::OrbExtractor> orb_;
	double route_m_ = 0;  //!< distance travelled, along the keyframes
	std::optional<uint64_t> lastKf_;
	std::map<uint64_t, double>
	    routeAt_;  //!< route distance when each online local map was finished
	std::size_t culledByDistance_ = 0, culledByLoop_ = 0, culledByCount_ = 0;
};
}  // namespace rasterslam

using namespace rasterslam;

IMPLEMENTS_MRPT_OBJECT(LocalMapManager, MapManager, rasterslam)

RASTERSLAM_REGISTER_CLASSES(register_rasterslam_plugin_local_map_manager)
{
	mrpt::rtti::registerClass(CLASS_ID(rasterslam::LocalMapManager));
}

void LocalMapManager::initializeImpl(ParamReader& p)
{
	keyframesPerMap_ = p.getInt("keyframes_per_map", keyframesPerMap_);
	placeQueryKeyframes_ = p.getInt("place_query_keyframes", placeQueryKeyframes_);
	placeQueryTurns_ = p.getInt("place_query_turns", placeQueryTurns_);
	polarContexts_ = p.getBool("polar_contexts", false);
	polar_ = places::PolarParams();
	polar_.rings = p.getInt("polar_rings", polar_.rings);
	polar_.sectors = p.getInt("polar_sectors", polar_.sectors);
	polar_.maxRange_m = p.getDouble("polar_range_m", polar_.maxRange_m);
	polar_.heightOffset_m = p.getDouble("polar_height_offset_m", polar_.heightOffset_m);
	maxExtent_m_ = p.getDouble("max_extent_m", maxExtent_m_);
	overlap_ = p.getBool("overlap", overlap_);
	localBa_ = p.getBool("local_ba", localBa_);
	ba_.maxIterations = p.getInt("ba_max_iterations", ba_.maxIterations);
	ba_.sigmaXY_m = p.getDouble("ba_sigma_xy_m", ba_.sigmaXY_m);
	ba_.sigmaZ_m = p.getDouble("ba_sigma_z_m", ba_.sigmaZ_m);
	ba_.huber = p.getDouble("ba_huber", ba_.huber);
	ba_.gate_m = p.getDouble("ba_gate_m", ba_.gate_m);
	ba_.maxHamming = p.getInt("ba_max_hamming", ba_.maxHamming);
	ba_.planar = p.getChoice("ba_dof", "full", {"planar", "full"}) == "planar";
	mapPointsPerFeature_ =
	    p.getChoice("map_points", "observations", {"observations", "tracks"}) == "observations";
	// The keyframe clouds hold no ground already.
	mapRaster_ = raster::localMapRasterParams(p.getDouble("map_resolution_m", 0.2),
	                                          p.getDouble("map_extent_m", 60.0));
	mapRaster_.canonicalYaw = p.getBool("canonical_yaw", false);
	mapOrb_.numFeatures = p.getInt("map_features", 3000);
	mapOrb_.levels = 3;
	cullDistance_m_ = p.getDouble("cull_distance_m", cullDistance_m_);
	cullOnLoop_ = p.getBool("cull_on_loop", cullOnLoop_);
	indexReplaced_ = p.getBool("index_replaced", indexReplaced_);
	maxOnlineMaps_ = p.getInt("max_online_maps", maxOnlineMaps_);
	offlineDir_ = p.getString("offline_dir", "");
	surfaceVoxel_m_ = p.getDouble("surface_voxel_m", surfaceVoxel_m_);
	surfaceRange_m_ = p.getDouble("surface_range_m", surfaceRange_m_);
	p.require(surfaceVoxel_m_ >= 0, surfaceVoxel_m_, "surface_voxel_m", "must be >= 0 (0: none)");
	if (surfaceVoxel_m_ > 0 && surfaceVoxel_m_ < 0.05)
		p.reject("surface_voxel_m", "must be at least 0.05 m (the surface is stored in cm)");
	p.requireRange(surfaceRange_m_, 1.0, 150.0, "surface_range_m");
	p.require(cullDistance_m_ >= 0, cullDistance_m_, "cull_distance_m", "must be >= 0 (0: never)");
	p.require(maxOnlineMaps_ >= 0, maxOnlineMaps_, "max_online_maps", "must be >= 0 (0: no bound)");
	p.requireRange(keyframesPerMap_, 1, static_cast<double>(LocalMap::kMaxKeyframes),
	               "keyframes_per_map");
	p.requireRange(placeQueryKeyframes_, 0, static_cast<double>(LocalMap::kMaxKeyframes),
	               "place_query_keyframes");
	p.requireRange(placeQueryTurns_, 1, 16, "place_query_turns");
	if (polarContexts_ && placeQueryKeyframes_ == 0)
		p.reject("polar_contexts",
		         "describes the place query of place_query_keyframes, which is 0");
	if (placeQueryTurns_ > 1 && placeQueryKeyframes_ == 0)
		p.reject("place_query_turns", "turns the image of place_query_keyframes, which is 0");
	if (placeQueryTurns_ > 1 && mapRaster_.canonicalYaw)
		p.reject("place_query_turns", "and canonical_yaw both turn the query's image: use one");
	p.requireRange(polar_.rings, 1, 255, "polar_rings");
	p.requireRange(polar_.sectors, 1, 720, "polar_sectors");
	p.requireRange(polar_.maxRange_m, 1.0, 500.0, "polar_range_m");
	p.requireRange(polar_.heightOffset_m, -10.0, 10.0, "polar_height_offset_m");
	p.requirePositive(maxExtent_m_, "max_extent_m");
	p.requireAtLeast(ba_.maxIterations, 1, "ba_max_iterations");
	p.requirePositive(ba_.sigmaXY_m, "ba_sigma_xy_m");
	p.requirePositive(ba_.sigmaZ_m, "ba_sigma_z_m");
	p.requirePositive(ba_.huber, "ba_huber");
	p.requirePositive(ba_.gate_m, "ba_gate_m");
	p.requireRange(ba_.maxHamming, 0, 256, "ba_max_hamming");  // ORB: 256-bit descriptors
	p.requirePositive(mapRaster_.resolution_m, "map_resolution_m");
	p.requirePositive(mapRaster_.maxRange_m, "map_extent_m");
	if (2 * mapRaster_.maxRange_m / mapRaster_.resolution_m > 8192)
		p.reject("map_resolution_m", "the local-map image would exceed 8192 pixels a side");
	p.requireRange(mapOrb_.numFeatures, 1, features::kMaxFeatures, "map_features");
	orb_ = std::make_unique<features::OrbExtractor>(mapOrb_);
	map_ = Map();
	map_.sessions = 1;
	session_ = 0;
	open_.clear();
	clouds_.clear();
	queryWindow_.clear();
	surfaces_.clear();
	pendingLoops_.clear();
	pendingRelocs_.clear();
	lastLocalMap_.reset();
	openSharesFirst_ = false;
	route_m_ = 0;
	lastKf_.reset();
	routeAt_.clear();
}

LocalMapManager::~LocalMapManager()
{
	if (ownOfflineDir_ && map_.offline)
	{
		std::error_code ec;
		std::filesystem::remove_all(map_.offline->dir(), ec);
	}
}

namespace
{
/** Offline folders that runs killed before their end left in the temporary folder
 *  (rasterslam-offline-PID-N of a process that is gone): removed, or a killed run's local
 *  maps would stay there. */
void removeStaleOfflineDirs(const std::filesystem::path& tmp)
{
	std::error_code ec;
	const std::string prefix = "rasterslam-offline-";
	for (const auto& e : std::filesystem::directory_iterator(tmp, ec))
	{
		const auto name = e.path().filename().string();
		if (name.rfind(prefix, 0) != 0 || !e.is_directory(ec))
			continue;
		const auto pid = name.substr(prefix.size(), name.find('-', prefix.size()) - prefix.size());
		if (pid.empty() || pid.size() > 9 ||
		    pid.find_first_not_of("0123456789") != std::string::npos)
			continue;
		const auto p = static_cast<pid_t>(std::stol(pid));
		if (p != ::getpid() && ::kill(p, 0) != 0 && errno == ESRCH)
			std::filesystem::remove_all(e.path(), ec);
	}
}
}  // namespace

LocalMapStore& LocalMapManager::store()
{
	if (!map_.offline)
	{
		auto dir = offlineDir_;
		if (dir.empty())
		{
			// Nothing asked to keep it: a folder of this run, removed when it ends (and by
			// the next run when this one is killed).
			static std::atomic<int> counter{0};
			if (counter == 0)
				removeStaleOfflineDirs(std::filesystem::temp_directory_path());
			dir =
			    (std::filesystem::temp_directory_path() /
			     mrpt::format("rasterslam-offline-%d-%d", static_cast<int>(::getpid()), counter++))
			        .string();
			ownOfflineDir_ = true;
		}
		map_.offline = std::make_shared<LocalMapStore>(dir);
	}
	return *map_.offline;
}

void LocalMapManager::goOffline(uint64_t localMap, const char* why)
{
	auto& lm = map_.localMaps.at(localMap);
	if (!lm->online)
		return;
	LocalMap copy = *lm;
	copy.online = false;
	store().save(copy);
	auto stub = std::make_shared<LocalMap>();
	stub->id = lm->id;
	stub->session = lm->session;
	stub->keyframes = lm->keyframes;
	stub->createdStamp = lm->createdStamp;
	stub->updatedStamp = lm->updatedStamp;
	stub->online = false;
	stub->imageResolution_m = lm->imageResolution_m;
	stub->imageExtent_m = lm->imageExtent_m;
	stub->baTracks = lm->baTracks;
	stub->baInitialRms_m = lm->baInitialRms_m;
	stub->baFinalRms_m = lm->baFinalRms_m;
	lm = stub;
	routeAt_.erase(localMap);
	MRPT_LOG_DEBUG_FMT("local map %llu offline (%s)", static_cast<unsigned long long>(localMap),
	                   why);
}

void LocalMapManager::cull()
{
	if (cullDistance_m_ > 0)
		for (auto it = routeAt_.begin(); it != routeAt_.end();)
		{
			const auto [id, at] = *it++;
			if (route_m_ - at > cullDistance_m_)
			{
				goOffline(id, "distance");
				++culledByDistance_;
			}
		}
	if (maxOnlineMaps_ > 0)
		while (routeAt_.size() > static_cast<std::size_t>(maxOnlineMaps_))
		{
			// The one finished longest ago along the route.
			auto oldest = routeAt_.begin();
			for (auto it = routeAt_.begin(); it != routeAt_.end(); ++it)
				if (it->second < oldest->second)
					oldest = it;
			goOffline(oldest->first, "count");
			++culledByCount_;
		}
}

MappingUpdate LocalMapManager::addKeyframe(const KeyframeInfo& kf, const Scan& scan,
                                           const RasterFrame* raster, const PoseView& poses)
{
	if (!kf.data)
		throw std::runtime_error(
		    "rasterslam::LocalMapManager needs keyframes with features: use an odometry that "
		    "provides them (e.g. "
		    "rasterslam::OrbOdometry)");
	if (map_.keyframes.count(kf.node))
		throw std::runtime_error("keyframe id " + std::to_string(kf.node) +
		                         " is already in the map");
	auto k = std::make_shared<Keyframe>(*kf.data);
	k->id = kf.node;
	k->session = session_;
	k->scanIndex = kf.scanIndex;
	k->stamp = kf.stamp;
	map_.keyframes[k->id] = k;
	// Both poses read now: an anchoring or an optimization since the last keyframe must not
	// count as distance travelled.
	if (lastKf_ && !kf.afterLoss && map_.keyframes.count(*lastKf_))
		route_m_ += poses.at(k->id).distanceTo(poses.at(*lastKf_));
	lastKf_ = k->id;
	auto& cloud = clouds_[k->id];
	if (raster)
		raster::appendImagePoints(*raster, scan.points, cloud);
	if (surfaceVoxel_m_ > 0)
		surfaces_[k->id] = features::voxelDownsample(scan.points, surfaceVoxel_m_, surfaceRange_m_);
	if (placeQueryKeyframes_ > 0)
	{
		// The query window, like a local map, never spans a gap in tracking, nor a jump of a
		// relocalization.
		if (kf.afterLoss || kf.locatedAt)
			queryWindow_.clear();
		queryWindow_.emplace_back(k->id, cloud);
		while (queryWindow_.size() > static_cast<std::size_t>(placeQueryKeyframes_))
			queryWindow_.pop_front();
	}

	MappingUpdate up;
	if (placeQueryKeyframes_ > 0)
		makePlaceQuery(k->id, poses, up);
	// A local map never spans a gap in tracking: its keyframes' relative poses must be real.
	if (kf.afterLoss && !open_.empty())
		finishOpen(poses, up, false);
	// After that: the edge belongs to the local map this keyframe starts or joins.
	if (kf.locatedAt)
		if (const auto maps = map_.localMapsOf(*kf.locatedAt);
		    !maps.empty() && std::find(pendingRelocs_.begin(), pendingRelocs_.end(),
		                               maps.front()) == pendingRelocs_.end())
			pendingRelocs_.push_back(maps.front());
	open_.push_back(k->id);
	bool full = static_cast<int>(open_.size()) >= keyframesPerMap_;
	if (!full && open_.size() > 1)
	{
		const auto d = poses.at(k->id).distanceTo(poses.at(open_.front()));
		full = d > maxExtent_m_;
	}
	if (full)
		finishOpen(poses, up, true);
	return up;
}

MappingUpdate LocalMapManager::finish(const PoseView& poses)
{
	MappingUpdate up;
	// Only the keyframe shared with the previous local map is open: nothing new to map.
	if (!(open_.size() == 1 && openSharesFirst_) && !open_.empty())
		finishOpen(poses, up, false);
	for (const auto k : open_)
		release(k);
	open_.clear();
	queryWindow_.clear();
	return up;
}

void LocalMapManager::loopAccepted(uint64_t fromKf, uint64_t /*toKf*/, double /*stamp*/)
{
	// The query keyframe is in the open local map: the edge is made when that map is done.
	const auto maps = map_.localMapsOf(fromKf);
	if (maps.empty())
		return;
	if (std::find(pendingLoops_.begin(), pendingLoops_.end(), maps.front()) == pendingLoops_.end())
		pendingLoops_.push_back(maps.front());
	// Paper, "Map Update": the revisited place gets a new local map from the current scans
	// (the open one); the older one leaves the online graph for the offline store.
	if (cullOnLoop_)
		for (const auto m : maps)
			if (map_.localMaps.at(m)->online && routeAt_.count(m))
			{
				goOffline(m, "loop");
				++culledByLoop_;
			}
}

void LocalMapManager::release(uint64_t kf)
{
	clouds_.erase(kf);
	surfaces_.erase(kf);
	if (const auto it = map_.keyframes.find(kf); it != map_.keyframes.end())
		it->second->releaseFeatures();
}

void LocalMapManager::finishOpen(const PoseView& poses, MappingUpdate& up, bool continues)
{
	const std::vector<uint64_t> ids = open_;
	const auto anchorPose = poses.at(ids.front());
	std::vector<mapping::BaFrame> frames;
	for (const auto id : ids)
	{
		const auto& k = *map_.keyframes.at(id);
		mapping::BaFrame f;
		f.descriptors = k.descriptors.data();
		f.xyz = k.xyz.data();
		f.n = k.size();
		f.T_anchor_frame = toIsometry(poses.at(id) - anchorPose);
		frames.push_back(f);
	}
	auto lm = std::make_shared<LocalMap>();
	lm->id = map_.nextLocalMapId();
	lm->session = session_;
	lm->keyframes = ids;
	lm->createdStamp = map_.keyframes.at(ids.front())->stamp;
	lm->updatedStamp = map_.keyframes.at(ids.back())->stamp;

	std::vector<Eigen::Isometry3d> T(frames.size());
	for (std::size_t i = 0; i < frames.size(); i++)
		T[i] = frames[i].T_anchor_frame;
	mapping::LocalBaResult ba;
	if (localBa_ && frames.size() >= 2)
		ba = mapping::localBundleAdjustment(frames, ba_);
	if (ba.ran)
	{
		T = ba.T_anchor_frame;
		up.anchor = ids.front();
		for (std::size_t i = 1; i < ids.size(); i++)
			up.T_anchor_kf.emplace_back(ids[i], toPose(T[i]));
		lm->baTracks = static_cast<uint32_t>(ba.tracks);
		lm->baInitialRms_m = static_cast<float>(ba.initialRms_m);
		lm->baFinalRms_m = static_cast<float>(ba.finalRms_m);
		if (!mapPointsPerFeature_)
		{
			for (const auto& p : ba.points)
				lm->xyz.insert(lm->xyz.end(), {p.x(), p.y(), p.z()});
			lm->descriptors = std::move(ba.descriptors);
			lm->observers = std::move(ba.observers);
		}
		else
			// Every observation keeps its descriptor (what a later query matches against, in
			// whatever viewpoint), at the position BA gave its point.
			for (std::size_t i = 0; i < frames.size(); i++)
				for (std::size_t j = 0; j < frames[i].n; j++)
				{
					const int pt = ba.pointOfFeature[i][j];
					const Eigen::Vector3f p =
					    pt >= 0 ? ba.points[static_cast<std::size_t>(pt)]
					            : (T[i] * Eigen::Vector3d(frames[i].xyz[3 * j],
					                                      frames[i].xyz[3 * j + 1],
					                                      frames[i].xyz[3 * j + 2]))
					                  .cast<float>();
					lm->xyz.insert(lm->xyz.end(), {p.x(), p.y(), p.z()});
					lm->descriptors.insert(lm->descriptors.end(), frames[i].descriptors + 32 * j,
					                       frames[i].descriptors + 32 * (j + 1));
					lm->observers.push_back(pt >= 0 ? ba.observers[static_cast<std::size_t>(pt)]
					                                : (1u << i));
				}
	}
	else
	{
		// No BA (disabled, or one keyframe): every feature is a point of its own.
		for (std::size_t i = 0; i < frames.size(); i++)
			for (std::size_t j = 0; j < frames[i].n; j++)
			{
				const Eigen::Vector3f p =
				    (T[i] * Eigen::Vector3d(frames[i].xyz[3 * j], frames[i].xyz[3 * j + 1],
				                            frames[i].xyz[3 * j + 2]))
				        .cast<float>();
				lm->xyz.insert(lm->xyz.end(), {p.x(), p.y(), p.z()});
				lm->descriptors.insert(lm->descriptors.end(), frames[i].descriptors + 32 * j,
				                       frames[i].descriptors + 32 * (j + 1));
				lm->observers.push_back(1u << i);
			}
	}

	// The local-map image: the keyframes' non-ground points in the anchor frame.
	std::vector<PointXYZI> pts;
	for (std::size_t i = 0; i < ids.size(); i++)
	{
		const auto it = clouds_.find(ids[i]);
		if (it == clouds_.end())
			continue;
		raster::appendMoved(it->second, T[i].cast<float>(), pts);
	}
	RasterFrame img;
	raster::rasterizeElevation(pts, raster::Plane(), mapRaster_, img);
	if (surfaceVoxel_m_ > 0)
		lm->surfaceCm = surfaceOf(ids, T);
	if (polarContexts_)
	{
		// About each keyframe: a later pass is near one of them wherever along the map it is.
		lm->contextRings = static_cast<uint16_t>(polar_.rings);
		lm->contextSectors = static_cast<uint16_t>(polar_.sectors);
		std::vector<PointXYZI> about;
		for (std::size_t i = 0; i < ids.size(); i++)
		{
			about.clear();
			raster::appendMoved(pts, T[i].inverse().cast<float>(), about);
			const auto cells = contextCells(about);
			lm->contextCells.insert(lm->contextCells.end(), cells.begin(), cells.end());
		}
	}
	MappingUpdate::Finished fin;
	fin.localMap = lm->id;
	fin.imageDescriptors = wordsOfImage(img.image.asCvMatRef());
	if (!cv::imencode(".png", img.image.asCvMatRef(), lm->imagePng))
		throw std::runtime_error("cannot encode the image of local map " + std::to_string(lm->id));
	lm->imageResolution_m = static_cast<float>(mapRaster_.resolution_m);
	lm->imageExtent_m = static_cast<float>(mapRaster_.maxRange_m);

	// Paper, Algorithm 1: the local map enters the local-map graph with its labels.
	if (lastLocalMap_)
		map_.graph.add(*lastLocalMap_, lm->id, LocalMapGraph::EdgeKind::Sequential,
		               lm->createdStamp);
	for (const auto other : pendingRelocs_)
		if (map_.localMaps.count(other))
			map_.graph.add(other, lm->id, LocalMapGraph::EdgeKind::Relocalization,
			               lm->createdStamp);
	for (const auto other : pendingLoops_)
	{
		map_.graph.add(other, lm->id, LocalMapGraph::EdgeKind::Loop, lm->updatedStamp);
		// The place now has a newer local map: the older one's place-index entry goes (also
		// when it went offline earlier, by distance), unless every version is to stay
		// searchable. One entry a place keeps the database and the query time flat on a route
		// driven again and again; the older image stays in the store, so its entry can be made
		// again.
		if (cullOnLoop_ && !indexReplaced_ && !map_.localMaps.at(other)->online)
			up.replaced.emplace_back(other, lm->id);
	}
	pendingLoops_.clear();
	pendingRelocs_.clear();
	map_.localMaps[lm->id] = lm;
	routeAt_[lm->id] = route_m_;
	up.finished.push_back(std::move(fin));
	cull();
	MRPT_LOG_DEBUG_FMT(
	    "local map %llu: %zu keyframes, %zu points, BA %s (%zu tracks, rms %.3f -> %.3f m)",
	    static_cast<unsigned long long>(lm->id), ids.size(), lm->points(),
	    ba.ran ? "ran" : "skipped", ba.tracks, ba.initialRms_m, ba.finalRms_m);

	// Consecutive local maps share the last keyframe: it stays open, with its features.
	open_.clear();
	if (continues && overlap_ && ids.size() > 1)
	{
		open_.push_back(ids.back());
		openSharesFirst_ = true;
		lastLocalMap_ = lm->id;
		for (std::size_t i = 0; i + 1 < ids.size(); i++)
			release(ids[i]);
	}
	else
	{
		openSharesFirst_ = false;
		if (continues)
			lastLocalMap_ = lm->id;
		else
			lastLocalMap_.reset();
		for (const auto id : ids)
			release(id);
	}
}

std::vector<int16_t> LocalMapManager::surfaceOf(const std::vector<uint64_t>& ids,
                                                const std::vector<Eigen::Isometry3d>& T) const
{
	std::vector<Eigen::Vector3f> all;
	for (std::size_t i = 0; i < ids.size(); i++)
		if (const auto it = surfaces_.find(ids[i]); it != surfaces_.end())
		{
			const Eigen::Isometry3f Tf = T[i].cast<float>();
			for (const auto& q : it->second)
				all.push_back(Tf * q);
		}
	const auto merged = features::voxelDownsample(all, surfaceVoxel_m_);
	std::vector<int16_t> out;
	out.reserve(3 * merged.size());
	constexpr float kMax = 32767.f / 100.f;
	for (const auto& p : merged)
	{
		if (!p.allFinite() || p.cwiseAbs().maxCoeff() > kMax)
			continue;  // beyond what 16 bits of cm hold: a local map is far smaller
		for (int a = 0; a < 3; a++)
			out.push_back(static_cast<int16_t>(std::lround(p[a] * 100.f)));
	}
	return out;
}

void LocalMapManager::loadMap(const std::string& dir)
{
	map_ = rasterslam::loadMap(dir);
	// The earlier sessions' local maps wait in the offline store: loop closure and
	// relocalization read them on demand, and memory does not grow with the map.
	for (auto& [id, lm] : map_.localMaps)
		if (lm->hasData())
		{
			// A map of version 1 or 2 (one file) came whole: its local maps go to the store.
			lm->online = true;
			goOffline(id, "prior session");
		}
	session_ = map_.sessions;
	map_.sessions = session_ + 1;
	open_.clear();
	clouds_.clear();
	queryWindow_.clear();
	pendingLoops_.clear();
	pendingRelocs_.clear();
	lastLocalMap_.reset();
	openSharesFirst_ = false;
	MRPT_LOG_INFO_FMT("map %s: %zu sessions, %zu keyframes, %zu local maps", dir.c_str(),
	                  static_cast<std::size_t>(session_), map_.keyframes.size(),
	                  map_.localMaps.size());
}

void LocalMapManager::describeSession(const SessionRecord& session)
{
	auto r = session;
	r.id = session_;
	map_.sessionRecords[session_] = r;
}

MapManager::Added LocalMapManager::addMap(const Map& other,
                                          const std::map<uint64_t, mrpt::poses::CPose3D>& poses,
                                          const std::vector<std::pair<uint64_t, uint64_t>>& links)
{
	Added out;
	// The other map's sessions, keyframes and local maps follow this map's, in their order.
	const uint32_t firstSession = session_;
	for (uint32_t s = 0; s < other.sessions; s++)
		out.sessionIds[s] = firstSession + s;
	uint64_t nextKf = map_.nextKeyframeId(), nextLm = map_.nextLocalMapId();
	for (const auto& [id, k] : other.keyframes)
		out.keyframeIds[id] = nextKf++;
	for (const auto& [id, lm] : other.localMaps)
		out.localMapIds[id] = nextLm++;
	for (const auto& [s, r] : other.sessionRecords)
	{
		auto copy = r;
		copy.id = out.sessionIds.at(s);
		map_.sessionRecords[copy.id] = copy;
	}
	for (const auto& [id, k] : other.keyframes)
	{
		const auto pose = poses.find(id);
		if (pose == poses.end())
			throw std::runtime_error("merge: keyframe " + std::to_string(id) + " has no pose");
		auto copy = std::make_shared<Keyframe>(*k);
		copy->id = out.keyframeIds.at(id);
		copy->session = out.sessionIds.at(k->session);
		copy->pose = pose->second;
		map_.priorPoses[copy->id] = pose->second;
		map_.keyframes[copy->id] = copy;
	}
	double lastStamp = 0;
	for (const auto& [id, stub] : other.localMaps)
	{
		auto lm = std::make_shared<LocalMap>(*other.data(id));
		lm->id = out.localMapIds.at(id);
		lm->session = out.sessionIds.at(lm->session);
		for (auto& k : lm->keyframes)
			k = out.keyframeIds.at(k);
		lm->online = true;
		lastStamp = std::max(lastStamp, lm->updatedStamp);
		// The place index needs the image's words: the image is kept losslessly, so they are
		// those the map had when it was made.
		MappingUpdate::Finished fin;
		fin.localMap = lm->id;
		fin.imageDescriptors = wordsOf(*lm);
		out.localMaps.push_back(std::move(fin));
		map_.localMaps[lm->id] = lm;
		goOffline(lm->id, "merged");
	}
	for (const auto& e : other.graph.edges)
		map_.graph.add(out.localMapIds.at(e.from), out.localMapIds.at(e.to), e.kind, e.stamp);
	for (const auto& [mine, theirs] : links)
	{
		if (!map_.localMaps.count(mine))
			throw std::runtime_error("merge: no local map " + std::to_string(mine));
		map_.graph.add(mine, out.localMapIds.at(theirs), LocalMapGraph::EdgeKind::Relocalization,
		               lastStamp);
	}
	map_.sessions = firstSession + other.sessions;
	session_ = map_.sessions;
	MRPT_LOG_INFO_FMT("merged %zu keyframes and %zu local maps of %u sessions",
	                  other.keyframes.size(), other.localMaps.size(), other.sessions);
	return out;
}

std::vector<uint8_t> LocalMapManager::wordsOfImage(const cv::Mat& image)
{
	std::vector<cv::KeyPoint> kps;
	cv::Mat desc;
	orb_->extract(image, kps, desc);
	return desc.rows > 0 ? std::vector<uint8_t>(desc.datastart, desc.dataend)
	                     : std::vector<uint8_t>{};
}

void LocalMapManager::makePlaceQuery(uint64_t kf, const PoseView& poses, MappingUpdate& up)
{
	const auto T_world_kf = poses.at(kf);
	std::vector<PointXYZI> pts;
	for (const auto& [id, cloud] : queryWindow_)
	{
		const auto pose = poses(id);
		if (!pose)
			continue;
		raster::appendMoved(cloud, toIsometry(*pose - T_world_kf).cast<float>(), pts);
	}
	if (pts.empty())
		return;
	RasterFrame img;
	raster::rasterizeElevation(pts, raster::Plane(), mapRaster_, img);
	up.placeQuery = wordsOfImage(img.image.asCvMatRef());
	if (polarContexts_)
	{
		up.placeQueryContext.rings = static_cast<uint16_t>(polar_.rings);
		up.placeQueryContext.sectors = static_cast<uint16_t>(polar_.sectors);
		up.placeQueryContext.cells = contextCells(pts);
	}
	// Rasterized turned, not the image warped: no resampling of the heights.
	for (int k = 1; k < placeQueryTurns_; k++)
	{
		raster::rasterizeElevationTurned(pts, raster::Plane(), mapRaster_,
		                                 static_cast<float>(k * (M_PI / 2) / placeQueryTurns_),
		                                 img);
		up.placeQueryTurns.push_back(wordsOfImage(img.image.asCvMatRef()));
	}
}

PlaceContext LocalMapManager::placeContextOf(const Scan& scan, const RasterFrame& raster) const
{
	PlaceContext c;
	if (!polarContexts_)
		return c;
	// The points its image keeps (ground removed), as a keyframe's enter the place query.
	std::vector<PointXYZI> pts;
	raster::appendImagePoints(raster, scan.points, pts);
	c.rings = static_cast<uint16_t>(polar_.rings);
	c.sectors = static_cast<uint16_t>(polar_.sectors);
	c.cells = contextCells(pts);
	return c;
}

std::vector<uint8_t> LocalMapManager::contextCells(const std::vector<PointXYZI>& pts) const
{
	return places::quantizedCells(places::polarContext(pts, polar_), LocalMap::kContextStep_m);
}

std::vector<uint8_t> LocalMapManager::wordsOf(const LocalMap& lm)
{
	if (lm.imagePng.empty())
		return {};
	// The image is kept losslessly: its words are those the local map had when it was made.
	const cv::Mat img = cv::imdecode(lm.imagePng, cv::IMREAD_GRAYSCALE);
	if (img.empty())
		throw std::runtime_error("the image of local map " + std::to_string(lm.id) +
		                         " cannot be decoded");
	return wordsOfImage(img);
}

std::vector<uint8_t> LocalMapManager::imageDescriptors(uint64_t localMap)
{
	return wordsOf(*map_.data(localMap));
}

std::size_t LocalMapManager::removeLocalMaps(const std::set<uint64_t>& ids)
{
	for (const auto id : ids)
	{
		const auto it = map_.localMaps.find(id);
		if (it == map_.localMaps.end())
			throw std::runtime_error("no local map " + std::to_string(id));
		if (std::find(open_.begin(), open_.end(), it->second->anchor()) != open_.end() ||
		    lastLocalMap_ == id)
			throw std::runtime_error("local map " + std::to_string(id) + " is being built on");
		map_.localMaps.erase(it);
		routeAt_.erase(id);
		if (map_.offline && map_.offline->contains(id))
		{
			std::error_code ec;
			std::filesystem::remove(map_.offline->pathOf(id), ec);
		}
		map_.saved.erase(id);  // its file in the map's store goes when the map is saved
	}
	auto& edges = map_.graph.edges;
	edges.erase(std::remove_if(edges.begin(), edges.end(),
	                           [&](const auto& e) { return ids.count(e.from) || ids.count(e.to); }),
	            edges.end());
	std::set<uint64_t> held;
	for (const auto& [id, lm] : map_.localMaps)
		held.insert(lm->keyframes.begin(), lm->keyframes.end());
	std::size_t removed = 0;
	for (auto it = map_.keyframes.begin(); it != map_.keyframes.end();)
		if (!held.count(it->first) && !clouds_.count(it->first))
		{
			map_.priorPoses.erase(it->first);
			it = map_.keyframes.erase(it);
			++removed;
		}
		else
			++it;
	return removed;
}

void LocalMapManager::saveMap(const std::string& dir, const PoseView& poses,
                              const std::string& placeIndexClass,
                              const std::vector<uint8_t>& placeIndex)
{
	map_.placeIndexClass = placeIndexClass;
	map_.placeIndex = placeIndex;
	// A session that added nothing (a prune, a merge, a run that saw no keyframe) is no
	// session of the map.
	bool added = false;
	for (const auto& [id, k] : map_.keyframes)
		added = added || k->session == session_;
	const uint32_t sessions = map_.sessions;
	std::optional<SessionRecord> record;
	// A session that added nothing (prune, merge) keeps what the map was saved with online.
	map_.keepOnline = added ? std::set<uint64_t>{} : map_.onlineWhenSaved;
	if (!added && map_.sessions == session_ + 1)
	{
		map_.sessions = session_;
		if (const auto it = map_.sessionRecords.find(session_); it != map_.sessionRecords.end())
		{
			record = it->second;
			map_.sessionRecords.erase(it);
		}
	}
	auto restore = [&]
	{
		map_.sessions = sessions;
		if (record)
			map_.sessionRecords[session_] = *record;
	};
	try
	{
		rasterslam::saveMap(map_, poses, dir);
	}
	catch (...)
	{
		map_.placeIndex.clear();
		restore();
		throw;
	}
	restore();
	map_.placeIndex.clear();
	map_.placeIndex.shrink_to_fit();
	MRPT_LOG_INFO_FMT("map saved to %s: %zu keyframes, %zu local maps", mapFilePath(dir).c_str(),
	                  map_.keyframes.size(), map_.localMaps.size());
}
