// Saving and loading the map relocalization needs, and relocalization itself.
#include <mrpt/io/CFileGZOutputStream.h>
#include <unistd.h>

#include "bow_loop_detector.h"

using namespace rasterslam;
using rasterslam::bow_loop::kPriorMapNodeOffset;

namespace
{
constexpr uint32_t kMapMagic = 0x504d5352;	// "RSMP"
constexpr uint8_t kMapVersion = 0;
std::string mapFile(const std::string& dir) { return (std::filesystem::path(dir) / "map.rsmap").string(); }
}  // namespace

void BowLoopDetector::saveMap(const std::string& dir, const mrpt::graphs::CNetworkOfPoses3DInf& graph)
{
	finishMap();  // even a one-scan run leaves a usable map
	if (maps_.empty()) throw std::runtime_error("no keyframe was made: there is no map to save");
	if (!vocab_)
	{
		if (maps_.size() < 2)
			throw std::runtime_error(
				"the online vocabulary needs at least 2 local maps and this run made " +
				std::to_string(maps_.size()) + ": give loop_detector.params.vocabulary_file");
		trainOnline();
	}
	for (std::size_t i = 0; i < maps_.size(); i++)
		if (!maps_[i].entry)
		{
			bow::BowVector b;
			vocab_->transform(maps_[i].desc, b);
			maps_[i].entry = db_.add(b);
			entryMap_[*maps_[i].entry] = i;
		}
	// Keyframe poses as optimized.
	for (auto& k : kfs_)
		if (const auto it = graph.nodes.find(k.node); it != graph.nodes.end()) k.pose = it->second;

	std::filesystem::create_directories(dir);
	const auto path = mapFile(dir);
	const auto tmp = path + ".tmp-" + std::to_string(::getpid());
	{
		mrpt::io::CFileGZOutputStream f;
		if (!f.open(tmp, 1)) throw std::runtime_error("cannot write map '" + path + "'");
		auto a = mrpt::serialization::archiveFrom(f);
		a << kMapMagic << kMapVersion << *vocab_ << db_;
		a << static_cast<uint64_t>(kfs_.size());
		for (const auto& k : kfs_)
		{
			Keyframe kf = k.data ? *k.data : Keyframe();
			kf.id = k.node >= kPriorMapNodeOffset ? k.node - kPriorMapNodeOffset : k.node;
			kf.descriptors.assign(k.desc.datastart, k.desc.dataend);
			kf.xyz.clear();
			for (const auto& q : k.pts) kf.xyz.insert(kf.xyz.end(), {q.x(), q.y(), q.z()});
			kf.stamp = k.stamp;
			kf.pose = k.pose;
			a << kf;
		}
		a << static_cast<uint64_t>(maps_.size());
		for (const auto& m : maps_)
		{
			std::vector<uint64_t> kidx(m.keyframes.begin(), m.keyframes.end());
			a << kidx << m.newestStamp << static_cast<int64_t>(m.entry ? int64_t(*m.entry) : -1) << m.image;
		}
	}
	std::filesystem::rename(tmp, path);
	// The local-map images, for a look: a fresh folder replaces the old one whole.
	const auto imgDir = std::filesystem::path(dir) / "localmaps";
	const auto tmpDir = std::filesystem::path(dir) / (".localmaps.tmp-" + std::to_string(::getpid()));
	std::filesystem::remove_all(tmpDir);
	std::filesystem::create_directories(tmpDir);
	for (std::size_t i = 0; i < maps_.size(); i++)
		if (!maps_[i].image.saveToFile((tmpDir / mrpt::format("%04zu.png", i)).string()))
			throw std::runtime_error("cannot write '" + (imgDir / mrpt::format("%04zu.png", i)).string() + "'");
	std::filesystem::remove_all(imgDir);
	std::filesystem::rename(tmpDir, imgDir);
	MRPT_LOG_INFO_FMT("map saved to %s: %zu keyframes, %zu local maps", path.c_str(), kfs_.size(), maps_.size());
}

void BowLoopDetector::loadMap(const std::string& dir)
{
	const auto path = mapFile(dir);
	std::error_code ec;
	if (!std::filesystem::exists(path, ec)) throw std::runtime_error("map '" + path + "' does not exist");
	try
	{
		mrpt::io::CFileGZInputStream f(path);
		auto a = mrpt::serialization::archiveFrom(f);
		uint32_t magic = 0;
		uint8_t version = 0;
		a >> magic >> version;
		if (magic != kMapMagic) throw std::runtime_error("not a rasterslam map");
		if (version != kMapVersion) throw std::runtime_error("unknown map version " + std::to_string(version));
		auto v = std::make_shared<bow::Vocabulary>();
		a >> *v >> db_;
		vocab_ = v;
		uint64_t nk = 0;
		a >> nk;
		kfs_.clear();
		for (uint64_t i = 0; i < nk; i++)
		{
			auto kf = std::make_shared<Keyframe>();
			a >> *kf;
			KeyframeData kd;
			// Nodes of an earlier session are not nodes of this run's graph: give them ids
			// that cannot collide with the new ones.
			kd.node = kPriorMapNodeOffset + kf->id;
			kd.stamp = kf->stamp;
			kd.pose = kf->pose;
			kd.desc.create(static_cast<int>(kf->size()), 32, CV_8U);
			for (std::size_t j = 0; j < kf->size(); j++)
			{
				std::memcpy(kd.desc.ptr<uint8_t>(static_cast<int>(j)), &kf->descriptors[32 * j], 32);
				kd.pts.emplace_back(kf->xyz[3 * j], kf->xyz[3 * j + 1], kf->xyz[3 * j + 2]);
			}
			kf->descriptors.clear();
			kf->xyz.clear();
			kd.data = kf;
			kfs_.push_back(std::move(kd));
		}
		uint64_t nm = 0;
		a >> nm;
		maps_.clear();
		entryMap_.clear();
		for (uint64_t i = 0; i < nm; i++)
		{
			LocalMap m;
			std::vector<uint64_t> kidx;
			int64_t entry = -1;
			a >> kidx >> m.newestStamp >> entry >> m.image;
			for (const auto k : kidx)
			{
				if (k >= kfs_.size()) throw std::runtime_error("local map refers to a missing keyframe");
				m.keyframes.push_back(static_cast<std::size_t>(k));
			}
			if (entry >= 0)
			{
				if (!db_.contains(static_cast<bow::Database::EntryId>(entry)))
					throw std::runtime_error("local map refers to a missing database entry");
				m.entry = static_cast<bow::Database::EntryId>(entry);
				entryMap_[*m.entry] = maps_.size();
			}
			maps_.push_back(std::move(m));
		}
	}
	catch (const std::exception& e)
	{
		std::string what = e.what();
		if (const auto pos = what.find("Message:"); pos != std::string::npos)
			what = what.substr(pos + 9, what.find('\n', pos) - pos - 9);
		throw std::runtime_error("cannot read map '" + path + "': " + what);
	}
	open_.clear();
	prevBow_.reset();
	online_ = false;  // the map's vocabulary stays
}

RelocalizationResult BowLoopDetector::relocalize(const Scan& scan, const RasterFrame& raster)
{
	RelocalizationResult res;
	if (!vocab_ || db_.size() == 0)
	{
		res.reason = "empty-map";
		return res;
	}
	std::vector<cv::KeyPoint> kps;
	cv::Mat all;
	orb_->extract(raster.image.asCvMatRef(), kps, all);
	cv::Mat desc(0, 32, CV_8U);
	std::vector<Eigen::Vector3f> pts;
	for (int i = 0; i < static_cast<int>(kps.size()); i++)
	{
		const int32_t idx = raster::pointAtPixel(raster, kps[i].pt.x, kps[i].pt.y, 1);
		if (idx < 0) continue;
		const auto& q = scan.points[static_cast<std::size_t>(idx)];
		pts.emplace_back(q.x, q.y, q.z);
		desc.push_back(all.row(i));
	}
	if (pts.size() < static_cast<std::size_t>(ransac_.minInliers))
	{
		res.reason = "features";
		return res;
	}
	bow::BowVector q;
	vocab_->transform(descriptorsOf(desc), q);
	const auto results = db_.query(q, static_cast<std::size_t>(maxCandidates_ + 1));
	if (results.empty())
	{
		res.reason = "candidates";
		return res;
	}
	res.reason = "inliers";
	for (const auto& r : results)
	{
		const auto mi = entryMap_.at(r.entry);
		std::size_t kfIdx = 0;
		const auto fit = verify(desc, pts, maps_[mi], static_cast<uint32_t>(scan.index * 17 + 3), kfIdx);
		if (fit.ok && fit.inliers.size() > res.inliers)
		{
			res.found = true;
			res.reason = "ok";
			res.localMap = mi;
			res.keyframe = kfs_[kfIdx].node;
			res.keyframeStamp = kfs_[kfIdx].stamp;
			res.score = r.score;
			res.inliers = fit.inliers.size();
			res.keyframePose = kfs_[kfIdx].pose;
			res.pose = kfs_[kfIdx].pose + toPose(fit.T);
		}
		else if (!res.found)
		{
			res.score = std::max(res.score, r.score);
			res.inliers = std::max(res.inliers, fit.inliers.size());
		}
	}
	return res;
}

void BowLoopDetector::transformKeyframes(const mrpt::poses::CPose3D& C)
{
	for (auto& k : kfs_)
		if (k.node < kPriorMapNodeOffset) k.pose = C + k.pose;  // this session's keyframes only
}
