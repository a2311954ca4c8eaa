#include <mrpt/io/CStream.h>
#include <mrpt/maps/CPointsMapXYZI.h>
#include <mrpt/maps/CSimplePointsMap.h>
#include <mrpt/maps/registerAllClasses.h>
#include <mrpt/obs/CActionCollection.h>
#include <mrpt/obs/CActionRobotMovement2D.h>
#include <mrpt/obs/CActionRobotMovement3D.h>
#include <mrpt/obs/CObservation3DRangeScan.h>
#include <mrpt/obs/CObservationOdometry.h>
#include <mrpt/obs/CObservationPointCloud.h>
#include <mrpt/obs/CObservationRobotPose.h>
#include <mrpt/obs/CObservationRotatingScan.h>
#include <mrpt/obs/CObservationVelodyneScan.h>
#include <mrpt/obs/CSensoryFrame.h>
#include <mrpt/obs/registerAllClasses.h>
#include <mrpt/poses/CPosePDFGaussian.h>
#include <mrpt/serialization/CArchive.h>
#include <rasterslam/io/rawlog_source.h>
#include <zlib.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <new>
#include <optional>
#include <stdexcept>

namespace rasterslam::io
{
namespace
{
/** Reads a rawlog, gzip or plain, counting the uncompressed bytes consumed so that a damaged
 *  object can be reported by its offset and a clean end told from a cut one. A gzip file is
 *  inflated by zlib, which also knows its position in the file (gzoffset) for the progress,
 *  right for files of any size (gzip's own size field is the size modulo 4 GiB). A plain file
 *  is read with stdio, whose large reads go straight into MRPT's buffers: zlib's transparent
 *  mode would copy every byte once more through its own buffer (measured on the KITTI sample:
 *  0.52 -> 0.43 ms of reading a 1.9 MB scan). */
class RawlogStream : public mrpt::io::CStream
{
   public:
	explicit RawlogStream(const std::string& path) : path_(path)
	{
		unsigned char magic[2] = {0, 0};
		if (std::FILE* probe = std::fopen(path.c_str(), "rb"))
		{
			const bool two = std::fread(magic, 1, 2, probe) == 2;
			std::fclose(probe);
			const bool gzip = two && magic[0] == 0x1f && magic[1] == 0x8b;
			if (!gzip)
			{
				plain_ = std::fopen(path.c_str(), "rb");
				if (plain_)
					std::setvbuf(plain_, nullptr, _IOFBF, 1 << 16);
				return;
			}
		}
		f_ = ::gzopen(path.c_str(), "rb");
		if (f_)
			::gzbuffer(f_, 1 << 18);
	}
	~RawlogStream() override
	{
		if (f_)
			::gzclose(f_);
		if (plain_)
			std::fclose(plain_);
	}
	RawlogStream(const RawlogStream&) = delete;
	RawlogStream& operator=(const RawlogStream&) = delete;
	bool isOpen() const { return f_ != nullptr || plain_ != nullptr; }
	size_t Read(void* buf, size_t n) override
	{
		const size_t done = readRaw(buf, n);
		watchCounts(static_cast<const unsigned char*>(buf), done);
		return done;
	}
	size_t readRaw(void* buf, size_t n)
	{
		if (plain_)
		{
			const size_t done = std::fread(buf, 1, n, plain_);
			if (done < n && std::ferror(plain_))
				throw std::runtime_error("read error: " + path_ + ": " + std::strerror(errno));
			count_ += done;
			return done;
		}
		size_t done = 0;
		while (done < n)
		{
			const auto want = static_cast<unsigned>(std::min<size_t>(n - done, 1u << 30));
			const int r = ::gzread(f_, static_cast<char*>(buf) + done, want);
			if (r < 0)
			{
				int code = 0;
				const char* msg = ::gzerror(f_, &code);
				throw std::runtime_error(std::string("gzip data error: ") +
				                         (msg ? msg : "unknown"));
			}
			if (r == 0)
				break;
			done += static_cast<size_t>(r);
		}
		count_ += done;
		return done;
	}
	size_t Write(const void*, size_t) override
	{
		throw std::logic_error("RawlogStream is read-only");
	}
	uint64_t Seek(int64_t, TSeekOrigin) override
	{
		throw std::logic_error("RawlogStream cannot seek");
	}
	uint64_t getTotalBytesCount() const override { return 0; }
	uint64_t getPosition() const override { return count_; }
	/** Uncompressed bytes consumed. */
	uint64_t count() const { return count_; }
	/** Bytes of the file consumed (compressed, for gzip). */
	uint64_t fileOffset() const
	{
		if (plain_)
			return count_;
		const auto o = ::gzoffset(f_);
		return o > 0 ? static_cast<uint64_t>(o) : 0;
	}

	/** The most entries a sensory frame or an action collection may claim. */
	static constexpr uint32_t kMaxEntries = 100000;
	/** Why the stream refused a count (empty: it has not). */
	const std::string& refusal() const { return refusal_; }

   private:
	/** MRPT sizes a CSensoryFrame's (and a CActionCollection's) container by the count it
	 *  reads, before any entry: a damaged count asks for gigabytes in blocks each small enough
	 *  to pass, and the program only stops at its memory cap, seconds later. The stream sees
	 *  the class name, the version byte and the count go by (three reads in a row) and refuses
	 *  a count no real frame has. */
	void watchCounts(const unsigned char* b, size_t n)
	{
		// The class name as MRPT 2 writes it (namespaced) or as older files have it.
		const auto is = [&](const char* name)
		{
			const std::string full = std::string("mrpt::obs::") + name;
			return (n == std::strlen(name) && std::memcmp(b, name, n) == 0) ||
			       (n == full.size() && std::memcmp(b, full.data(), n) == 0);
		};
		switch (watch_)
		{
			case Watch::None:
				if (is("CSensoryFrame") || is("CActionCollection"))
				{
					watch_ = Watch::Version;
					watchedClass_ = is("CSensoryFrame") ? "CSensoryFrame" : "CActionCollection";
				}
				return;
			case Watch::Version:
				watch_ = n == 1 ? Watch::Count : Watch::None;
				return;
			case Watch::Count:
				watch_ = Watch::None;
				if (n == 4)
				{
					uint32_t c = 0;
					std::memcpy(&c, b, 4);  // MRPT archives are little-endian
					if (c > kMaxEntries)
					{
						// Kept: MRPT wraps the exception in its own message.
						refusal_ = "a " + watchedClass_ + " claims " + std::to_string(c) +
						           " entries (at most " + std::to_string(kMaxEntries) +
						           " are plausible): a damaged count";
						throw std::runtime_error(refusal_);
					}
				}
				return;
		}
	}
	enum class Watch
	{
		None,
		Version,
		Count
	};
	Watch watch_ = Watch::None;
	std::string watchedClass_, refusal_;
	std::string path_;
	gzFile f_ = nullptr;
	std::FILE* plain_ = nullptr;
	uint64_t count_ = 0;
};

void registerClassesOnce()
{
	// Debian links with --as-needed: without these calls the classes are not registered.
	static const bool done = []
	{
		mrpt::obs::registerAllClasses_mrpt_obs();
		mrpt::maps::registerAllClasses_mrpt_maps();
		return true;
	}();
	(void)done;
}

std::vector<double> defaultElevations(int rows)
{
	std::vector<double> e(rows);
	double lo = 0, hi = 0;
	if (rows == 16)
		lo = -15, hi = 15;
	else if (rows == 32)
		lo = -30.67, hi = 10.67;
	else if (rows == 64)
		lo = -24.8, hi = 2.0;
	else
		return {};
	for (int i = 0; i < rows; i++)
		e[i] = lo + (hi - lo) * i / (rows - 1);
	return e;
}

/** Points of four parallel arrays (x, y, z, intensity or none), read as one sequence: lets
 *  std::vector::assign build each point in place. Its reference is a value (the point is made
 *  on the fly), which std::vector::assign accepts: it only copies through it. */
struct ZipPoints
{
	using iterator_category = std::random_access_iterator_tag;
	using value_type = PointXYZI;
	using difference_type = std::ptrdiff_t;
	using pointer = const PointXYZI*;
	using reference = PointXYZI;
	const float *x = nullptr, *y = nullptr, *z = nullptr, *i = nullptr;
	std::size_t k = 0;
	PointXYZI operator*() const { return {x[k], y[k], z[k], i ? i[k] : 0.f}; }
	ZipPoints& operator++()
	{
		++k;
		return *this;
	}
	ZipPoints& operator--()
	{
		--k;
		return *this;
	}
	ZipPoints operator++(int)
	{
		auto old = *this;
		++k;
		return old;
	}
	ZipPoints& operator+=(difference_type d)
	{
		k = static_cast<std::size_t>(static_cast<difference_type>(k) + d);
		return *this;
	}
	ZipPoints& operator-=(difference_type d) { return *this += -d; }
	ZipPoints operator+(difference_type d) const
	{
		auto r = *this;
		return r += d;
	}
	ZipPoints operator-(difference_type d) const
	{
		auto r = *this;
		return r -= d;
	}
	difference_type operator-(const ZipPoints& o) const
	{
		return static_cast<difference_type>(k) - static_cast<difference_type>(o.k);
	}
	PointXYZI operator[](difference_type d) const { return *(*this + d); }
	bool operator==(const ZipPoints& o) const { return k == o.k; }
	bool operator!=(const ZipPoints& o) const { return k != o.k; }
	bool operator<(const ZipPoints& o) const { return k < o.k; }
	bool operator<=(const ZipPoints& o) const { return k <= o.k; }
	bool operator>(const ZipPoints& o) const { return k > o.k; }
	bool operator>=(const ZipPoints& o) const { return k >= o.k; }
};

void appendTransformed(std::vector<PointXYZI>& out, const mrpt::poses::CPose3D& sensorPose, float x,
                       float y, float z, float i)
{
	double gx, gy, gz;
	sensorPose.composePoint(x, y, z, gx, gy, gz);
	out.push_back({static_cast<float>(gx), static_cast<float>(gy), static_cast<float>(gz), i});
}
}  // namespace

bool observationToPoints(const mrpt::obs::CObservation& o, std::vector<PointXYZI>& out,
                         const RawlogSourceOptions& opts, const std::string& source)
{
	using namespace mrpt::obs;
	out.clear();
	if (const auto* pc = dynamic_cast<const CObservationPointCloud*>(&o))
	{
		if (pc->isExternallyStored() && !std::filesystem::exists(pc->getExternalStorageFile()))
			throw std::runtime_error(source + ": point cloud '" + pc->sensorLabel +
			                         "' refers to external file '" + pc->getExternalStorageFile() +
			                         "', which does not exist");
		pc->load();  // no-op unless externally stored
		if (!pc->pointcloud)
		{
			if (pc->isExternallyStored())
				throw std::runtime_error(
				    source + ": point cloud '" + pc->sensorLabel + "' refers to external file '" +
				    pc->getExternalStorageFile() + "', which could not be loaded");
			return true;  // an empty cloud: the engine reports it
		}
		const auto& m = *pc->pointcloud;
		const auto& xs = m.getPointsBufferRef_x();
		const auto& ys = m.getPointsBufferRef_y();
		const auto& zs = m.getPointsBufferRef_z();
		const auto* xyzi = dynamic_cast<const mrpt::maps::CPointsMapXYZI*>(&m);
		// Capacity in steps of 32768 points (512 kB): the scans of a run then take blocks of a
		// few sizes, and a freed one fits the next, instead of each leaving a hole in the heap
		// that a scan a few points larger cannot use (resident memory crept up by some MB
		// every few hundred scans).
		out.reserve((xs.size() / 32768 + 1) * 32768);
		const std::size_t n = std::min({xs.size(), ys.size(), zs.size()});
		const float* is = nullptr;
		if (xyzi && xyzi->getPointsBufferRef_intensity().size() >= n)
			is = xyzi->getPointsBufferRef_intensity().data();
		// One pass over plain arrays, each point built in place (no per-point capacity check,
		// no zero fill first): half the reading time of a plain rawlog went here otherwise. A
		// sensor pose to apply (rare) takes a zero-filled buffer and a second pass.
		if (pc->sensorPose == mrpt::poses::CPose3D())
			out.assign(ZipPoints{xs.data(), ys.data(), zs.data(), is, 0},
			           ZipPoints{xs.data(), ys.data(), zs.data(), is, n});
		else
		{
			out.resize(n);
			PointXYZI* o = out.data();
			const auto& R = pc->sensorPose.getRotationMatrix();
			const double tx = pc->sensorPose.x(), ty = pc->sensorPose.y(), tz = pc->sensorPose.z();
			for (std::size_t k = 0; k < n; k++)
			{
				const double x = xs[k], y = ys[k], z = zs[k];
				o[k] = {static_cast<float>(R(0, 0) * x + R(0, 1) * y + R(0, 2) * z + tx),
				        static_cast<float>(R(1, 0) * x + R(1, 1) * y + R(1, 2) * z + ty),
				        static_cast<float>(R(2, 0) * x + R(2, 1) * y + R(2, 2) * z + tz),
				        is ? is[k] : 0.f};
			}
		}
		if (pc->isExternallyStored())
			pc->unload();  // keep memory flat
		return true;
	}
	if (const auto* vs = dynamic_cast<const CObservationVelodyneScan*>(&o))
	{
		const CObservationVelodyneScan* src = vs;
		CObservationVelodyneScan tmp;
		if (vs->point_cloud.x.empty())
		{
			tmp = *vs;
			tmp.generatePointCloud();
			src = &tmp;
		}
		const auto& pcl = src->point_cloud;
		out.reserve(pcl.x.size());
		for (size_t k = 0; k < pcl.x.size(); k++)
			appendTransformed(out, vs->sensorPose, pcl.x[k], pcl.y[k], pcl.z[k],
			                  pcl.intensity[k] / 255.f);
		return true;
	}
	if (const auto* rs = dynamic_cast<const CObservationRotatingScan*>(&o))
	{
		std::vector<double> elev = opts.rotatingScanElevationsDeg;
		if (elev.empty())
			elev = defaultElevations(rs->rowCount);
		if (elev.size() != rs->rowCount)
			throw std::runtime_error(source + ": CObservationRotatingScan '" + rs->sensorLabel +
			                         "' has " + std::to_string(rs->rowCount) +
			                         " rows; no beam elevation table for that count (give one with "
			                         "rotatingScanElevationsDeg)");
		const bool hasI = rs->intensityImage.rows() == rs->rowCount &&
		                  rs->intensityImage.cols() == rs->columnCount;
		const double dAz = rs->columnCount > 1 ? rs->azimuthSpan / (rs->columnCount - 1) : 0.0;
		for (int r = 0; r < rs->rowCount; r++)
		{
			const double el = elev[r] * M_PI / 180.0, ce = std::cos(el), se = std::sin(el);
			for (int c = 0; c < rs->columnCount; c++)
			{
				const auto raw = rs->rangeImage(r, c);
				if (raw == 0)
					continue;  // no return
				const double range = raw * rs->rangeResolution;
				const double az = rs->startAzimuth + c * dAz;
				appendTransformed(
				    out, rs->sensorPose, static_cast<float>(range * ce * std::cos(az)),
				    static_cast<float>(range * ce * std::sin(az)), static_cast<float>(range * se),
				    hasI ? rs->intensityImage(r, c) / 255.f : 0.f);
			}
		}
		return true;
	}
	if (const auto* r3 = dynamic_cast<const CObservation3DRangeScan*>(&o))
	{
		r3->load();
		mrpt::maps::CSimplePointsMap m;
		if (r3->hasPoints3D)
		{
			for (size_t k = 0; k < r3->points3D_x.size(); k++)
				appendTransformed(out, r3->sensorPose, r3->points3D_x[k], r3->points3D_y[k],
				                  r3->points3D_z[k], 0.f);
		}
		else if (r3->hasRangeImage)
		{
			mrpt::obs::T3DPointsProjectionParams pp;
			pp.takeIntoAccountSensorPoseOnRobot = true;
			const_cast<CObservation3DRangeScan*>(r3)->unprojectInto(m, pp);
			const auto& xs = m.getPointsBufferRef_x();
			const auto& ys = m.getPointsBufferRef_y();
			const auto& zs = m.getPointsBufferRef_z();
			for (size_t k = 0; k < xs.size(); k++)
				out.push_back({xs[k], ys[k], zs[k], 0.f});
		}
		r3->unload();
		return true;
	}
	return false;
}

struct RawlogSource::Impl
{
	std::unique_ptr<RawlogStream> counting;
	uint64_t fileSize = 0;
};

RawlogSource::RawlogSource(const std::string& path, RawlogSourceOptions opts)
    : impl_(std::make_unique<Impl>()), path_(path), opts_(std::move(opts))
{
	registerClassesOnce();
	std::error_code ec;
	if (!std::filesystem::exists(path, ec))
		throw std::runtime_error("cannot open rawlog '" + path + "': no such file");
	if (std::filesystem::is_directory(path, ec))
		throw std::runtime_error("cannot open rawlog '" + path + "': it is a directory");
	impl_->counting = std::make_unique<RawlogStream>(path);
	if (!std::ifstream(path).good() || !impl_->counting->isOpen())
		throw std::runtime_error("cannot open rawlog '" + path + "': not readable");
	impl_->fileSize = std::filesystem::file_size(path, ec);
}

RawlogSource::~RawlogSource() = default;

double RawlogSource::progress() const
{
	// The share of the file read (compressed bytes for gzip): right whatever its size.
	if (impl_->fileSize == 0)
		return -1;
	return std::min(1.0, static_cast<double>(impl_->counting->fileOffset()) /
	                         static_cast<double>(impl_->fileSize));
}

void RawlogSource::attachGroundTruth(int64_t ticks, const mrpt::poses::CPose3D& pose)
{
	if (pending_ && pendingTicks_ == ticks && !pending_->groundTruth)
	{
		pending_->groundTruth = pose;
		return;
	}
	earlyGt_.emplace_back(ticks, pose);
	if (earlyGt_.size() > 16)
		earlyGt_.pop_front();  // only ever needed for the next scan
}

void RawlogSource::addOdometryIncrement(const mrpt::poses::CPose3DPDFGaussian& inc)
{
	if (!pendingOdometry_)
		pendingOdometry_ = inc;
	else
		*pendingOdometry_ += inc;  // composition with covariance propagation
}

void RawlogSource::handleObservation(const mrpt::obs::CObservation& obs)
{
	using namespace mrpt::obs;
	const int64_t ticks = obs.timestamp.time_since_epoch().count();
	if (const auto* od = dynamic_cast<const CObservationOdometry*>(&obs))
	{
		// Absolute 2D readings: the increment is the difference of successive ones.
		if (lastOdometryReading_)
		{
			mrpt::poses::CPose3DPDFGaussian inc(
			    mrpt::poses::CPose3D(od->odometry - *lastOdometryReading_));
			inc.cov.setZero();
			addOdometryIncrement(inc);
		}
		lastOdometryReading_ = od->odometry;
		return;
	}
	if (const auto* gt = dynamic_cast<const CObservationRobotPose*>(&obs))
	{
		attachGroundTruth(ticks, gt->pose.mean);
		return;
	}
	if (!opts_.sensorLabel.empty() && obs.sensorLabel != opts_.sensorLabel)
		return;
	Scan s;
	if (!observationToPoints(obs, s.points, opts_, path_))
		return;
	s.index = scans_++;
	s.odometryIncrement = pendingOdometry_;
	pendingOdometry_.reset();
	s.stamp = mrpt::Clock::toDouble(obs.timestamp);
	s.sensorLabel = obs.sensorLabel;
	for (auto it = earlyGt_.begin(); it != earlyGt_.end(); ++it)
		if (it->first == ticks)
		{
			s.groundTruth = it->second;
			earlyGt_.erase(it);
			break;
		}
	if (pending_)
		ready_.push_back(std::move(*pending_));
	pending_ = std::move(s);
	pendingTicks_ = ticks;
}

bool RawlogSource::readOne()
{
	auto arch = mrpt::serialization::archiveFrom(*impl_->counting);
	const uint64_t before = impl_->counting->count();
	mrpt::serialization::CSerializable::Ptr obj;
	// A damaged count or size: the allocation it asked for failed (the programs cap their
	// memory, see capMemory() in apps/common; MRPT may wrap the std::bad_alloc).
	const auto tooBig = [&]
	{
		return path_ + ": corrupt object at uncompressed byte " + std::to_string(before) +
		       " (after " + std::to_string(scans_) +
		       " scans): it asks for more memory than this process may use (a damaged count or "
		       "size; RASTERSLAM_MAX_MEMORY_MB sets the cap)";
	};
	try
	{
		obj = arch.ReadObject();
	}
	catch (const mrpt::serialization::CExceptionEOF&)
	{
		if (impl_->counting->count() == before)
			return false;  // clean end between objects
		stopReason_ =
		    path_ +
		    ": truncated: the file ends inside the object that starts at uncompressed byte " +
		    std::to_string(before) + " (after " + std::to_string(scans_) + " scans)";
		return false;
	}
	catch (const std::bad_alloc&)
	{
		stopReason_ = tooBig();
		return false;
	}
	catch (const std::exception& e)
	{
		// MRPT nests exceptions ("Original exception: ..."); the innermost message says most.
		if (std::string(e.what()).find("std::bad_alloc") != std::string::npos)
		{
			stopReason_ = tooBig();
			return false;
		}
		if (!impl_->counting->refusal().empty())
		{
			stopReason_ = path_ + ": corrupt object at uncompressed byte " +
			              std::to_string(before) + " (after " + std::to_string(scans_) +
			              " scans): " + impl_->counting->refusal();
			return false;
		}
		const std::string full = e.what();
		std::string what = full;
		for (auto pos = full.find("Message:"); pos != std::string::npos;
		     pos = full.find("Message:", pos + 1))
		{
			const auto end = full.find('\n', pos);
			what =
			    full.substr(pos + 9, end == std::string::npos ? std::string::npos : end - pos - 9);
		}
		if (objects_ == 0 && full.find("EOF") == std::string::npos)
			throw std::runtime_error(
			    path_ + ": not an MRPT rawlog (the first object cannot be read): " + what);
		if (full.find("EOF") != std::string::npos ||
		    full.find("Cannot read requested number") != std::string::npos)
			stopReason_ =
			    path_ +
			    ": truncated: the file ends inside the object that starts at uncompressed byte " +
			    std::to_string(before) + " (after " + std::to_string(scans_) + " scans)";
		else
			stopReason_ = path_ + ": corrupt object at uncompressed byte " +
			              std::to_string(before) + " (after " + std::to_string(scans_) +
			              " scans): " + what;
		return false;
	}
	++objects_;
	try
	{
		dispatch(obj);
	}
	catch (const std::exception& e)
	{
		// A scan that cannot be turned into points (a missing external file...) ends the
		// stream like damage does: what was read before it is still processed.
		std::string what = e.what();
		if (const auto pos = what.find("Message:"); pos != std::string::npos)
			what = what.substr(pos + 9, what.find('\n', pos) - pos - 9);
		if (const auto pos = what.find("Call stack"); pos != std::string::npos)
			what.resize(pos);
		stopReason_ = what + " (object at uncompressed byte " + std::to_string(before) +
		              ", after " + std::to_string(scans_) + " scans)";
		return false;
	}
	return true;
}

void RawlogSource::dispatch(const mrpt::serialization::CSerializable::Ptr& obj)
{
	if (auto sf = std::dynamic_pointer_cast<mrpt::obs::CSensoryFrame>(obj))
	{
		for (const auto& o : *sf)
			if (o)
				handleObservation(*o);
	}
	else if (auto o = std::dynamic_pointer_cast<mrpt::obs::CObservation>(obj))
		handleObservation(*o);
	else if (auto acts = std::dynamic_pointer_cast<mrpt::obs::CActionCollection>(obj))
	{
		for (const auto& a : *acts)
		{
			if (const auto* m3 = dynamic_cast<const mrpt::obs::CActionRobotMovement3D*>(a.get()))
				addOdometryIncrement(m3->poseChange);
			else if (const auto* m2 =
			             dynamic_cast<const mrpt::obs::CActionRobotMovement2D*>(a.get()))
			{
				if (!m2->poseChange)
					continue;
				mrpt::poses::CPosePDFGaussian g;
				g.copyFrom(*m2->poseChange);
				addOdometryIncrement(mrpt::poses::CPose3DPDFGaussian(g));
			}
		}
	}
	// Other objects carry no scans or odometry: skipped.
}

std::optional<Scan> RawlogSource::next()
{
	while (ready_.empty() && !ended_)
		if (!readOne())
			ended_ = true;
	if (!ready_.empty())
	{
		Scan s = std::move(ready_.front());
		ready_.pop_front();
		return s;
	}
	if (pending_)
	{
		Scan s = std::move(*pending_);
		pending_.reset();
		return s;
	}
	if (objects_ == 0 && stopReason_.empty())
		throw std::runtime_error(path_ + ": empty file, not an MRPT rawlog");
	return std::nullopt;
}

}  // namespace rasterslam::io
