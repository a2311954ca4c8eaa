// Writing MRPT rawlogs (observations-only format), gz-compressed or plain.
#pragma once

#include <rasterslam/core/types.h>

#include <memory>
#include <string>

namespace mrpt::serialization
{
class CSerializable;
}

namespace rasterslam::io
{
/** Streams observations into an MRPT rawlog ("observations-only" format: a sequence of
 *  CObservation objects), so that MRPT's own tools (rawlog-edit, RawLogViewer) open it.
 *  The file is written under a temporary name and renamed on close(); an unclosed writer
 *  (an exception, a crash) removes its temporary file and leaves any older file in place. */
class RawlogWriter
{
   public:
	/** compressLevel: 0 writes a plain file, 1..9 a gzip stream (MRPT reads both). */
	explicit RawlogWriter(const std::string& path, int compressLevel = 0);
	~RawlogWriter();
	RawlogWriter(const RawlogWriter&) = delete;
	RawlogWriter& operator=(const RawlogWriter&) = delete;

	/** Writes the scan as a CObservationPointCloud holding a CPointsMapXYZI (sensorPose:
	 *  identity, label scan.sensorLabel or "LIDAR"), then, if the scan has ground truth, a
	 *  CObservationRobotPose with the same time stamp. */
	void writeScan(const Scan& scan);
	/** Writes any serializable MRPT object as the next entry. */
	void write(const mrpt::serialization::CSerializable& obj);
	/** Flushes, closes and renames the temporary file to its final name. */
	void close();

	const std::string& path() const { return path_; }
	std::size_t count() const { return count_; }

   private:
	struct Impl;
	std::unique_ptr<Impl> impl_;
	std::string path_;
	std::size_t count_ = 0;
};

}  // namespace rasterslam::io
