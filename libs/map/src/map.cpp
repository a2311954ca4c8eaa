#include <fcntl.h>
#include <mrpt/io/CFileGZInputStream.h>
#include <mrpt/io/CFileGZOutputStream.h>
#include <mrpt/io/CMemoryStream.h>
#include <mrpt/serialization/CArchive.h>
#include <mrpt/serialization/stl_serialization.h>
#include <mrpt/system/crc.h>
#include <rasterslam/map/map.h>
#include <signal.h>
#include <sys/file.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <set>
#include <stdexcept>

namespace fs = std::filesystem;

namespace rasterslam
{
namespace
{
constexpr uint32_t kMapMagic = 0x504d5352;  // "RSMP"
// Version 0 (the loop detector's own file, before the map model) is not read: its keyframe
// grouping cannot be turned into local maps with points.
// Version 1 has no session records; versions 1 and 2 hold every local map whole in the one
// file; version 3 is an index, the local maps being files of the map's store; version 4 is
// version 3 with the body's length and CRC-32 ahead of it.
constexpr uint8_t kMapVersion = 4;
constexpr uint64_t kMaxIndexBytes = uint64_t(4) << 30;
/** The index after its magic and version (and, from version 4, its length and checksum). */
void readIndexBody(mrpt::serialization::CArchive& a, uint8_t version, const std::string& dir,
                   Map& map);
}  // namespace

std::optional<mrpt::poses::CPose3D> PoseView::operator()(uint64_t keyframe) const
{
	if (live)
		if (const auto* p = live(keyframe))
			return *p;
	if (prior)
		if (const auto it = prior->find(keyframe); it != prior->end())
			return it->second;
	return std::nullopt;
}

mrpt::poses::CPose3D PoseView::at(uint64_t keyframe) const
{
	const auto p = (*this)(keyframe);
	if (!p)
		throw std::runtime_error("keyframe " + std::to_string(keyframe) + " has no pose");
	return *p;
}

uint64_t Map::nextKeyframeId() const
{
	return keyframes.empty() ? 0 : keyframes.rbegin()->first + 1;
}
uint64_t Map::nextLocalMapId() const
{
	return localMaps.empty() ? 0 : localMaps.rbegin()->first + 1;
}

LocalMap::ConstPtr Map::data(uint64_t localMap) const
{
	const auto& lm = localMaps.at(localMap);
	if (lm->online || lm->hasData())
		return lm;
	std::lock_guard<std::mutex> lk(cache_.mutex);
	for (const auto& c : cache_.maps)
		if (c->id == localMap)
			return c;
	LocalMap::ConstPtr loaded;
	if (const auto it = saved.find(localMap); it != saved.end() && savedStore)
		loaded = savedStore->loadFile(it->second.file, localMap);
	else if (offline)
		loaded = offline->load(localMap);
	else
		throw std::runtime_error("local map " + std::to_string(localMap) +
		                         " is offline and there is no store");
	// A loop query verifies a handful of candidates: keep the last few, not the store.
	cache_.maps.push_back(loaded);
	if (cache_.maps.size() > 8)
		cache_.maps.pop_front();
	return loaded;
}

std::size_t Map::onlineCount() const
{
	std::size_t n = 0;
	for (const auto& [id, lm] : localMaps)
		n += lm->online;
	return n;
}

std::vector<uint64_t> Map::localMapsOf(uint64_t keyframe) const
{
	std::vector<uint64_t> out;
	for (const auto& [id, lm] : localMaps)
		if (lm->keyframeIndex(keyframe) >= 0)
			out.push_back(id);
	return out;
}

std::size_t Map::memoryBytes() const
{
	std::size_t b = 0;
	for (const auto& [id, k] : keyframes)
		b += sizeof(Keyframe) + k->xyz.capacity() * 4 + k->descriptors.capacity() +
		     k->u.capacity() * 16 + k->octave.capacity();
	for (const auto& [id, lm] : localMaps)
		b += lm->memoryBytes();
	return b + placeIndex.capacity();
}

std::string mapFilePath(const std::string& dir)
{
	return (fs::path(dir) / "map.rsmap").string();
}

namespace
{
/** Flushes a file or folder to the disk: a map named by an index that survived a power cut
 *  must find its files whole. Best effort (a file system may not support it). */
void syncPath(const fs::path& p)
{
	const int fd = ::open(p.c_str(), O_RDONLY);
	if (fd < 0)
		return;
	::fsync(fd);
	::close(fd);
}

/** An exclusive lock on DIR/.lock for the time of a save. */
class FolderLock
{
   public:
	explicit FolderLock(const std::string& dir)
	{
		const auto path = (fs::path(dir) / ".lock").string();
		fd_ = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC | O_NOFOLLOW, 0644);
		if (fd_ < 0)
			throw std::runtime_error("cannot write in map folder '" + dir +
			                         "': " + std::strerror(errno));
		if (::flock(fd_, LOCK_EX) != 0)
		{
			::close(fd_);
			throw std::runtime_error("cannot lock map folder '" + dir +
			                         "': " + std::strerror(errno));
		}
	}
	~FolderLock() { ::close(fd_); }
	FolderLock(const FolderLock&) = delete;
	FolderLock& operator=(const FolderLock&) = delete;

   private:
	int fd_ = -1;
};

/** Temporary files an interrupted save left behind (their process is gone): a killed save
 *  must not leave them to fill the disk. */
void removeStaleTemporaries(const std::string& dir)
{
	std::error_code ec;
	for (const auto& e : fs::directory_iterator(dir, ec))
	{
		const auto name = e.path().filename().string();
		const auto at = name.rfind(".tmp-");
		if (at == std::string::npos)
			continue;
		const auto stem = name.substr(0, at);
		const auto ends = [&](const std::string& x) {
			return stem.size() >= x.size() &&
			       stem.compare(stem.size() - x.size(), x.size(), x) == 0;
		};
		if (stem != "map.rsmap" && stem != ".localmaps" && !ends(".rslm") && !ends(".png"))
			continue;
		const std::string pid = name.substr(at + 5);
		if (pid.empty() || pid.find_first_not_of("0123456789") != std::string::npos ||
		    pid.size() > 9)
			continue;
		const auto p = static_cast<pid_t>(std::stol(pid));
		if (p != ::getpid() && ::kill(p, 0) != 0 && errno == ESRCH)
			fs::remove_all(e.path(), ec);
	}
}
}  // namespace

MapUseLock::MapUseLock(const std::string& dir, Mode mode, const std::string& what)
{
	const auto path = (fs::path(dir) / ".use.lock").string();
	fd_ = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC | O_NOFOLLOW, 0644);
	if (fd_ < 0 && mode == Mode::Read && errno != ELOOP)
		fd_ = ::open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NOFOLLOW);
	if (fd_ < 0)
	{
		if (mode == Mode::Read)
			return;  // a read-only folder: nobody can save there either
		throw std::runtime_error("cannot write in map folder '" + dir +
		                         "': " + std::strerror(errno));
	}
	if (::flock(fd_, (mode == Mode::Write ? LOCK_EX : LOCK_SH) | LOCK_NB) == 0)
	{
		if (mode == Mode::Write)
		{
			// Who writes, for the message another process gives.
			const std::string who = "process " + std::to_string(::getpid()) + " (" + what + ")\n";
			if (::ftruncate(fd_, 0) == 0)
				(void)!::pwrite(fd_, who.data(), who.size(), 0);
		}
		return;
	}
	const int err = errno;
	// Held by readers (a shared lock can still be had) or by a writer (named in the file).
	bool writer = true;
	if (mode == Mode::Write && ::flock(fd_, LOCK_SH | LOCK_NB) == 0)
	{
		writer = false;
		::flock(fd_, LOCK_UN);
	}
	std::string who;
	if (writer)
	{
		char buf[256] = {};
		const auto n = ::pread(fd_, buf, sizeof(buf) - 1, 0);
		who.assign(buf, n > 0 ? static_cast<std::size_t>(n) : 0);
		while (!who.empty() && (who.back() == '\n' || who.back() == '\r'))
			who.pop_back();
	}
	::close(fd_);
	fd_ = -1;
	if (err != EWOULDBLOCK)
		throw std::runtime_error("cannot lock map folder '" + dir + "': " + std::strerror(err));
	throw std::runtime_error("map folder '" + dir + "' is in use: " +
	                         (writer ? (who.empty() ? std::string("another process") : who) +
	                                       " is writing it; wait until it ends"
	                                 : std::string("other processes are reading it; wait until "
	                                               "they end")));
}

MapUseLock::~MapUseLock()
{
	if (fd_ >= 0)
		::close(fd_);
}

void saveMap(const Map& map, const PoseView& poses, const std::string& dir)
{
	if (map.localMaps.empty())
		throw std::runtime_error("the map has no local map: there is nothing to save");
	fs::create_directories(dir);
	// One writer at a time: another process's cleanup must not remove files this save is
	// about to name (the lock goes with the descriptor, also when the process is killed).
	const FolderLock lock(dir);
	removeStaleTemporaries(dir);
	const LocalMapStore store((fs::path(dir) / "store").string());
	removeStaleTemporaries(store.dir());
	std::error_code ec;
	// Saving over the map it was loaded from: its local maps' files are there already.
	const bool sameStore = map.savedStore && fs::equivalent(map.savedStore->dir(), store.dir(), ec);

	// 1. The local maps' files (the only big writes; new content only).
	std::map<uint64_t, LocalMapStore::Entry> entries;
	std::vector<uint64_t> fresh;  // written now: their images too
	for (const auto& [id, stub] : map.localMaps)
	{
		if (const auto it = map.saved.find(id);
		    sameStore && it != map.saved.end() &&
		    fs::is_regular_file(fs::path(store.dir()) / it->second.file, ec))
		{
			entries[id] = it->second;
			continue;
		}
		// Offline local maps are read back one at a time: every observation is kept.
		entries[id] = store.saveContent(*map.data(id));
		fresh.push_back(id);
	}

	// 2. The new local maps' images, for a look (nothing refers to them, so before the index).
	const auto imgDir = fs::path(dir) / "localmaps";
	fs::create_directories(imgDir);
	removeStaleTemporaries(imgDir.string());
	syncPath(store.dir());
	const std::set<uint64_t> isFresh(fresh.begin(), fresh.end());
	for (const auto& [id, stub] : map.localMaps)
	{
		const auto name = imgDir / mrpt::format("%04llu.png", static_cast<unsigned long long>(id));
		// New ones, and any a killed save did not get to.
		if (!isFresh.count(id) && fs::exists(name, ec))
			continue;
		const auto lm = map.data(id);
		if (lm->imagePng.empty())
			continue;
		const auto tmpImg = name.string() + ".tmp-" + std::to_string(::getpid());
		std::ofstream o(tmpImg, std::ios::binary);
		o.write(reinterpret_cast<const char*>(lm->imagePng.data()),
		        static_cast<std::streamsize>(lm->imagePng.size()));
		o.close();
		if (!o)
		{
			fs::remove(tmpImg, ec);
			throw std::runtime_error("cannot write '" + name.string() + "'");
		}
		fs::rename(tmpImg, name);
	}
	// 3. The index, renamed into place last: until then the previous map is the map.
	const auto path = mapFilePath(dir);
	const auto tmp = path + ".tmp-" + std::to_string(::getpid());
	try
	{
		// The body in memory first: the file carries its length and CRC-32 ahead of it.
		mrpt::io::CMemoryStream body;
		auto a = mrpt::serialization::archiveFrom(body);
		a << map.sessions;
		a << static_cast<uint32_t>(map.sessionRecords.size());
		for (const auto& [id, r] : map.sessionRecords)
			a << r.id << r.firstStamp << r.startedAt << r.sensor << r.input;
		a << static_cast<uint64_t>(map.keyframes.size());
		for (const auto& [id, k] : map.keyframes)
		{
			Keyframe out = *k;
			out.pose = poses.at(id);
			a << out;
		}
		a << static_cast<uint64_t>(map.localMaps.size());
		for (const auto& [id, lm] : map.localMaps)
		{
			// Labels only: the points and the image are in the store file.
			LocalMap labels;
			labels.id = lm->id;
			labels.session = lm->session;
			labels.keyframes = lm->keyframes;
			labels.createdStamp = lm->createdStamp;
			labels.updatedStamp = lm->updatedStamp;
			labels.online = lm->online || map.keepOnline.count(id) > 0;
			labels.imageResolution_m = lm->imageResolution_m;
			labels.imageExtent_m = lm->imageExtent_m;
			labels.baTracks = lm->baTracks;  // run reports read them without the points
			labels.baInitialRms_m = lm->baInitialRms_m;
			labels.baFinalRms_m = lm->baFinalRms_m;
			const auto& e = entries.at(id);
			a << labels << e.file << e.points << e.bytes;
		}
		a << map.graph << map.placeIndexClass << map.placeIndex;
		const auto* bytes = static_cast<const uint8_t*>(body.getRawBufferData());
		const uint64_t n = body.getTotalBytesCount();
		const uint32_t crc = mrpt::system::compute_CRC32(bytes, n);
		mrpt::io::CFileGZOutputStream f;
		if (!f.open(tmp, 1))
			throw std::runtime_error("cannot write map '" + path + "'");
		auto header = mrpt::serialization::archiveFrom(f);
		header << kMapMagic << kMapVersion << n << crc;
		if (f.Write(bytes, n) != n)
			throw std::runtime_error("cannot write map '" + path + "' (disk full?)");
		f.close();
	}
	catch (...)
	{
		fs::remove(tmp, ec);
		throw;
	}
	syncPath(tmp);
	fs::rename(tmp, path);
	syncPath(dir);

	// 4. What the index no longer names.
	std::set<std::string> named;
	for (const auto& [id, e] : entries)
		named.insert(e.file);
	for (const auto& e : fs::directory_iterator(store.dir(), ec))
		if (e.path().extension() == ".rslm" && !named.count(e.path().filename().string()))
			fs::remove(e.path(), ec);
	for (const auto& e : fs::directory_iterator(imgDir, ec))
	{
		const auto stem = e.path().stem().string();
		if (e.path().extension() != ".png" ||
		    stem.find_first_not_of("0123456789") != std::string::npos)
			continue;
		if (stem.empty() || stem.size() > 18)
			continue;
		if (!map.localMaps.count(std::stoull(stem)))
			fs::remove(e.path(), ec);
	}
}

Map loadMap(const std::string& dir)
{
	const auto path = mapFilePath(dir);
	std::error_code ec;
	if (!fs::exists(path, ec))
		throw std::runtime_error("map '" + path + "' does not exist");
	if (!fs::is_regular_file(path, ec))
		throw std::runtime_error("map '" + path + "' is not a file");
	Map map;
	try
	{
		mrpt::io::CFileGZInputStream f(path);
		auto a = mrpt::serialization::archiveFrom(f);
		uint32_t magic = 0;
		uint8_t version = 0;
		a >> magic >> version;
		if (magic != kMapMagic)
			throw std::runtime_error("not a rasterslam map");
		if (version == 0)
			throw std::runtime_error(
			    "map version 0 (written before the map manager): build the map again");
		if (version > kMapVersion)
			throw std::runtime_error("unknown map version " + std::to_string(version));
		if (version < 4)
			readIndexBody(a, version, dir, map);
		else
		{
			// Length and CRC-32 of the body, checked before any of it is parsed.
			uint64_t n = 0;
			uint32_t crc = 0;
			a >> n >> crc;
			if (n > kMaxIndexBytes)
				throw std::runtime_error("damaged header: a body of " + std::to_string(n) +
				                         " bytes");
			std::vector<uint8_t> bytes;
			// In steps: a damaged length runs into the end of the file, not into memory.
			constexpr uint64_t kStep = uint64_t(64) << 20;
			while (bytes.size() < n)
			{
				const auto want = std::min<uint64_t>(kStep, n - bytes.size());
				const auto had = bytes.size();
				bytes.resize(had + want);
				if (f.Read(bytes.data() + had, want) != want)
					throw std::runtime_error("truncated: the body is " + std::to_string(n) +
					                         " bytes, the file ends after " + std::to_string(had) +
					                         " of them");
			}
			if (mrpt::system::compute_CRC32(bytes) != crc)
				throw std::runtime_error("checksum mismatch (the file is damaged)");
			mrpt::io::CMemoryStream body;
			body.assignMemoryNotOwn(bytes.data(), bytes.size());
			auto b = mrpt::serialization::archiveFrom(body);
			readIndexBody(b, version, dir, map);
			if (body.getPosition() != n)
				throw std::runtime_error("the body has " + std::to_string(n - body.getPosition()) +
				                         " bytes past its end");
		}
	}
	catch (const std::exception& e)
	{
		std::string what = e.what();
		if (const auto pos = what.find("Message:"); pos != std::string::npos)
			what = what.substr(pos + 9, what.find('\n', pos) - pos - 9);
		if (const auto pos = what.find("Call stack"); pos != std::string::npos)
			what.resize(pos);
		while (!what.empty() && (what.back() == '\n' || what.back() == ' '))
			what.pop_back();
		throw std::runtime_error("cannot read map '" + path + "': " + what);
	}
	return map;
}

namespace
{
void readIndexBody(mrpt::serialization::CArchive& a, uint8_t version, const std::string& dir,
                   Map& map)
{
	std::error_code ec;
	{
		a >> map.sessions;
		if (version >= 2)
		{
			uint32_t n = 0;
			a >> n;
			if (n > map.sessions)
				throw std::runtime_error(std::to_string(n) + " session records for " +
				                         std::to_string(map.sessions) + " sessions");
			for (uint32_t i = 0; i < n; i++)
			{
				SessionRecord r;
				a >> r.id >> r.firstStamp >> r.startedAt >> r.sensor >> r.input;
				if (r.id >= map.sessions)
					throw std::runtime_error("session record " + std::to_string(r.id) + " of " +
					                         std::to_string(map.sessions) + " sessions");
				map.sessionRecords[r.id] = r;
			}
		}
		uint64_t nk = 0;
		a >> nk;
		for (uint64_t i = 0; i < nk; i++)
		{
			auto k = std::make_shared<Keyframe>();
			a >> *k;
			if (map.keyframes.count(k->id))
				throw std::runtime_error("keyframe id " + std::to_string(k->id) + " twice");
			if (version >= 2 && k->session >= map.sessions)
				throw std::runtime_error("keyframe " + std::to_string(k->id) + " of session " +
				                         std::to_string(k->session) + " in a map of " +
				                         std::to_string(map.sessions) + " sessions");
			map.priorPoses[k->id] = k->pose;
			map.keyframes[k->id] = k;
		}
		uint64_t nm = 0;
		a >> nm;
		if (version >= 3)
			map.savedStore = std::make_shared<LocalMapStore>((fs::path(dir) / "store").string());
		for (uint64_t i = 0; i < nm; i++)
		{
			auto lm = std::make_shared<LocalMap>();
			a >> *lm;
			if (version >= 3)
			{
				LocalMapStore::Entry e;
				a >> e.file >> e.points >> e.bytes;
				// NNNNNN-CCCCCCCC.rslm of this very local map: nothing outside the store is named.
				const auto idPart =
				    mrpt::format("%06llu-", static_cast<unsigned long long>(lm->id));
				if (e.file.size() != idPart.size() + 13 ||
				    e.file.compare(0, idPart.size(), idPart) != 0 ||
				    e.file.compare(e.file.size() - 5, 5, ".rslm") != 0 ||
				    e.file.find_first_not_of("0123456789abcdef", idPart.size()) !=
				        e.file.size() - 5)
					throw std::runtime_error("local map " + std::to_string(lm->id) +
					                         ": bad file name '" + e.file + "'");
				if (!fs::is_regular_file(fs::path(map.savedStore->dir()) / e.file, ec))
					throw std::runtime_error(
					    "local map " + std::to_string(lm->id) + ": its file '" +
					    (fs::path(map.savedStore->dir()) / e.file).string() + "' is missing");
				map.saved[lm->id] = e;
			}
			for (const auto k : lm->keyframes)
				if (!map.keyframes.count(k))
					throw std::runtime_error("local map " + std::to_string(lm->id) +
					                         " refers to missing keyframe " + std::to_string(k));
			if (version >= 2 && lm->session >= map.sessions)
				throw std::runtime_error("local map " + std::to_string(lm->id) + " of session " +
				                         std::to_string(lm->session) + " in a map of " +
				                         std::to_string(map.sessions) + " sessions");
			if (map.localMaps.count(lm->id))
				throw std::runtime_error("local map id " + std::to_string(lm->id) + " twice");
			if (lm->online)
				map.onlineWhenSaved.insert(lm->id);
			// Read from a file, every local map is offline: in the store (version 3) or, for
			// older maps, in memory whole (Map::data serves it either way).
			if (version >= 3)
				lm->online = false;
			map.localMaps[lm->id] = lm;
		}
		a >> map.graph >> map.placeIndexClass >> map.placeIndex;
		for (const auto& e : map.graph.edges)
			if (!map.localMaps.count(e.from) || !map.localMaps.count(e.to))
				throw std::runtime_error("the local-map graph refers to a missing local map");
	}
}
}  // namespace

}  // namespace rasterslam
