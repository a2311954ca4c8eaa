// The whole map: keyframes, local maps and their graph, and the map file.
#pragma once

#include <mrpt/poses/CPose3D.h>
#include <rasterslam/map/keyframe.h>
#include <rasterslam/map/local_map.h>
#include <rasterslam/map/local_map_store.h>

#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <vector>

namespace rasterslam
{
/** Keyframe poses as their owners hold them: `live` are the nodes of the running session's
 *  pose graph (the optimizer writes them), `prior` the keyframes of a loaded map that are
 *  not nodes of it. Readers never keep copies: they look poses up when they need them. */
struct PoseView
{
	std::function<const mrpt::poses::CPose3D*(uint64_t)> live;
	const std::map<uint64_t, mrpt::poses::CPose3D>* prior = nullptr;

	std::optional<mrpt::poses::CPose3D> operator()(uint64_t keyframe) const;
	/** Throws naming the keyframe when it has no pose. */
	mrpt::poses::CPose3D at(uint64_t keyframe) const;
};

/** A session: one run (or one map merged in) that added keyframes and local maps. */
struct SessionRecord
{
	uint32_t id = 0;
	double firstStamp = 0;  //!< the first scan's time stamp (the input's clock)
	std::string startedAt;  //!< wall-clock time the session was made, ISO 8601 UTC
	std::string sensor;     //!< sensor label of its scans
	std::string input;      //!< what it read (the rawlog's path), or the merged map's folder
	bool operator==(const SessionRecord& o) const
	{
		return id == o.id && firstStamp == o.firstStamp && startedAt == o.startedAt &&
		       sensor == o.sensor && input == o.input;
	}
};

/** The map model. The map manager is its only writer; the loop detector and the engine read
 *  it through a const reference. */
class Map
{
   public:
	std::map<uint64_t, Keyframe::Ptr> keyframes;
	/** Every local map. One that left the online graph (online == false) is a stub here:
	 *  labels and stamps only; its points and image are in `offline` or `savedStore`. */
	std::map<uint64_t, LocalMap::Ptr> localMaps;
	/** The offline store of this run (null: nothing went offline). */
	std::shared_ptr<LocalMapStore> offline;
	/** The store of the map folder this map was loaded from (null: none), and the local maps
	 *  whose points and image are read from it when needed (loadMap keeps only labels in
	 *  memory). */
	std::shared_ptr<LocalMapStore> savedStore;
	std::map<uint64_t, LocalMapStore::Entry> saved;
	LocalMapGraph graph;
	/** Poses of the keyframes loaded from a saved map (fixed in this session). */
	std::map<uint64_t, mrpt::poses::CPose3D> priorPoses;
	/** The loop detector's place index, saved with the map and opaque to it (MRPT archive
	 *  bytes), with the class that wrote it. */
	std::string placeIndexClass;
	std::vector<uint8_t> placeIndex;
	/** Sessions stored in the map (the next session's id is this count). */
	uint32_t sessions = 0;
	/** Local maps that were online when the map was saved (filled by loadMap()). */
	std::set<uint64_t> onlineWhenSaved;
	/** Local maps saveMap() marks online although they are offline here (a map tool saving
	 *  a map it only changed keeps the flags it was saved with). */
	std::set<uint64_t> keepOnline;
	/** What is known of each session (maps of version 1 have none). */
	std::map<uint32_t, SessionRecord> sessionRecords;

	uint64_t nextKeyframeId() const;
	uint64_t nextLocalMapId() const;
	/** A local map with its points and image: the online one, or one loaded from the offline
	 *  store on demand (the last few loaded are kept). Throws naming the file on damage. */
	LocalMap::ConstPtr data(uint64_t localMap) const;
	/** Online local maps. */
	std::size_t onlineCount() const;
	/** The local maps that hold a keyframe (one, or two where consecutive ones overlap). */
	std::vector<uint64_t> localMapsOf(uint64_t keyframe) const;
	/** Bytes held in memory by keyframes and local maps. */
	std::size_t memoryBytes() const;

   private:
	/** The local maps last read from the offline store; a copy of the map starts without. */
	struct Cache
	{
		std::mutex mutex;
		std::deque<LocalMap::ConstPtr> maps;
		Cache() = default;
		Cache(const Cache&) {}
		Cache& operator=(const Cache&)
		{
			std::lock_guard<std::mutex> lk(mutex);
			maps.clear();
			return *this;
		}
	};
	mutable Cache cache_;
};

/** Writes the map into `dir`: every local map's points and image as a file of
 *  `dir/store/` (named by id and content; files the folder holds already are not written
 *  again), then the index `dir/map.rsmap` (gzip MRPT archive: magic, version, sessions,
 *  keyframes with the poses `poses` gives, local-map labels and their files, graph, place
 *  index), then `dir/localmaps/NNNN.png` of new local maps; each under a temporary name
 *  first. Store files and images no longer named by the index go last: a save stopped at
 *  any point leaves the previous map loadable. */
void saveMap(const Map& map, const PoseView& poses, const std::string& dir);
/** Reads a map written by saveMap(); throws naming the file and what is wrong. Keyframe
 *  poses go to `priorPoses`. Local maps come back as labels, their points read from
 *  `dir/store/` on demand (maps of versions 1 and 2, one file, are read whole). */
Map loadMap(const std::string& dir);
std::string mapFilePath(const std::string& dir);

/** A process's use of a map folder, held for the whole of its work on the map (advisory:
 *  flock(2) on `DIR/.use.lock`). One writer (a run with --map-out, `map prune`, `map merge`'s
 *  output) and nothing else, or any number of readers (a run with --map-in alone, `relocalize`,
 *  `map merge`'s inputs): a save deletes the store files its index no longer names, which a
 *  reader may still load on demand, and two writers would each save over the other's work.
 *  A conflict throws at once (no waiting) naming the folder and, for a writer, its process.
 *  The kernel drops the lock when the process ends, also when it is killed. A reader that
 *  cannot create the lock file (a read-only folder) goes on without a lock. */
class MapUseLock
{
   public:
	enum class Mode
	{
		Read,
		Write
	};
	/** `dir` must exist. `what` is recorded for others' messages (e.g. "rasterslam run"). */
	MapUseLock(const std::string& dir, Mode mode, const std::string& what);
	~MapUseLock();
	MapUseLock(const MapUseLock&) = delete;
	MapUseLock& operator=(const MapUseLock&) = delete;
	/** False for a reader that went on without a lock. */
	bool held() const { return fd_ >= 0; }

   private:
	int fd_ = -1;
};

}  // namespace rasterslam
