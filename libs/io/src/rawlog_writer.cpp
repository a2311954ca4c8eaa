#include <mrpt/io/CFileGZOutputStream.h>
#include <mrpt/io/CFileOutputStream.h>
#include <mrpt/maps/CPointsMapXYZI.h>
#include <mrpt/obs/CObservationPointCloud.h>
#include <mrpt/obs/CObservationRobotPose.h>
#include <mrpt/serialization/CArchive.h>
#include <rasterslam/io/rawlog_writer.h>
#include <unistd.h>

#include <filesystem>
#include <stdexcept>

namespace rasterslam::io
{
struct RawlogWriter::Impl
{
	std::string tmpPath;
	std::unique_ptr<mrpt::io::CStream> stream;
	bool closed = false;
};

RawlogWriter::RawlogWriter(const std::string& path, int compressLevel)
    : impl_(std::make_unique<Impl>()), path_(path)
{
	if (compressLevel < 0 || compressLevel > 9)
		throw std::invalid_argument("RawlogWriter: compression level must be 0..9, got " +
		                            std::to_string(compressLevel));
	impl_->tmpPath = path + ".tmp-" + std::to_string(::getpid());
	bool ok = false;
	if (compressLevel == 0)
	{
		auto f = std::make_unique<mrpt::io::CFileOutputStream>();
		ok = f->open(impl_->tmpPath);
		impl_->stream = std::move(f);
	}
	else
	{
		auto f = std::make_unique<mrpt::io::CFileGZOutputStream>();
		ok = f->open(impl_->tmpPath, compressLevel);
		impl_->stream = std::move(f);
	}
	if (!ok)
		throw std::runtime_error("cannot write rawlog '" + path + "': cannot create '" +
		                         impl_->tmpPath + "'");
}

RawlogWriter::~RawlogWriter()
{
	if (impl_ && !impl_->closed)
	{
		impl_->stream.reset();
		std::error_code ec;
		std::filesystem::remove(impl_->tmpPath, ec);
	}
}

void RawlogWriter::write(const mrpt::serialization::CSerializable& obj)
{
	if (impl_->closed)
		throw std::logic_error("RawlogWriter::write after close()");
	auto arch = mrpt::serialization::archiveFrom(*impl_->stream);
	arch << obj;
	++count_;
}

void RawlogWriter::writeScan(const Scan& scan)
{
	const auto stamp = mrpt::Clock::fromDouble(scan.stamp);
	mrpt::obs::CObservationPointCloud obs;
	obs.timestamp = stamp;
	obs.sensorLabel = scan.sensorLabel.empty() ? std::string("LIDAR") : scan.sensorLabel;
	auto pts = mrpt::maps::CPointsMapXYZI::Create();
	pts->resize(scan.points.size());
	for (size_t i = 0; i < scan.points.size(); i++)
	{
		const auto& p = scan.points[i];
		// XYZI maps keep intensity in the "R" channel.
		pts->setPointRGB(i, p.x, p.y, p.z, p.intensity, p.intensity, p.intensity);
	}
	obs.pointcloud = pts;
	write(obs);

	if (scan.groundTruth)
	{
		mrpt::obs::CObservationRobotPose gt;
		gt.timestamp = stamp;
		gt.sensorLabel = "GROUND_TRUTH";
		gt.pose.mean = *scan.groundTruth;
		gt.pose.cov.setZero();
		write(gt);
	}
}

void RawlogWriter::close()
{
	if (impl_->closed)
		return;
	impl_->stream.reset();  // flushes and closes the file
	std::error_code ec;
	std::filesystem::rename(impl_->tmpPath, path_, ec);
	if (ec)
		throw std::runtime_error("cannot write rawlog '" + path_ +
		                         "': rename from temporary file failed: " + ec.message());
	impl_->closed = true;
}

}  // namespace rasterslam::io
