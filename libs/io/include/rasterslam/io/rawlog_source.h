// Streaming reader of MRPT rawlogs as a ScanSource.
#pragma once

#include <mrpt/poses/CPose2D.h>
#include <mrpt/poses/CPose3DPDFGaussian.h>
#include <rasterslam/core/scan_source.h>

#include <deque>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace mrpt::obs
{
class CObservation;
}
namespace mrpt::serialization
{
class CSerializable;
}

namespace rasterslam::io
{
struct RawlogSourceOptions
{
	/** Only observations with this sensor label become scans (empty: any 3D scan). */
	std::string sensorLabel;
	/** Beam elevations (degrees, row 0 first) for CObservationRotatingScan, which carries
	 *  no calibration in MRPT 2.5. Empty: a table is chosen by the row count (16: VLP-16,
	 *  32: HDL-32E, 64: HDL-64E), with row 0 the lowest beam. */
	std::vector<double> rotatingScanElevationsDeg;
};

/** Reads a rawlog of either format (actions/sensory-frames or observations only), gzip
 *  compressed or plain, one object at a time: memory does not grow with the file size.
 *  Yields a Scan for every CObservationPointCloud (also externally stored),
 *  CObservationVelodyneScan, CObservationRotatingScan and CObservation3DRangeScan; a
 *  CObservationRobotPose with the same time stamp as a scan becomes its ground truth.
 *  Odometry in the input (CActionRobotMovement2D/3D in action collections, successive
 *  CObservationOdometry readings) is composed, with its covariance, into each scan's
 *  odometryIncrement (the motion since the previous scan).
 *  A missing or unreadable file, or one that does not start with an MRPT object, throws.
 *  Damage later in the file ends the stream: stopReason() gives the byte offset. */
class RawlogSource : public ScanSource
{
   public:
	explicit RawlogSource(const std::string& path, RawlogSourceOptions opts = {});
	~RawlogSource() override;

	std::optional<Scan> next() override;
	std::string name() const override { return path_; }
	double progress() const override;
	std::string stopReason() const override { return stopReason_; }

	/** Objects read so far (of any class). */
	std::size_t objectsRead() const { return objects_; }

   private:
	bool readOne();  // false at the end (normal or damage)
	void dispatch(const std::shared_ptr<mrpt::serialization::CSerializable>& obj);
	void handleObservation(const mrpt::obs::CObservation& obs);
	void attachGroundTruth(int64_t stampTicks, const mrpt::poses::CPose3D& pose);

	struct Impl;
	std::unique_ptr<Impl> impl_;
	std::string path_;
	RawlogSourceOptions opts_;
	std::size_t objects_ = 0, scans_ = 0;
	std::optional<Scan> pending_;  // last scan read: its ground truth may still follow
	int64_t pendingTicks_ = 0;
	std::deque<Scan> ready_;
	std::deque<std::pair<int64_t, mrpt::poses::CPose3D>> earlyGt_;  // ground truth seen first
	void addOdometryIncrement(const mrpt::poses::CPose3DPDFGaussian& inc);
	std::optional<mrpt::poses::CPose3DPDFGaussian> pendingOdometry_;  // since the last scan
	std::optional<mrpt::poses::CPose2D> lastOdometryReading_;         // CObservationOdometry
	bool ended_ = false;
	std::string stopReason_;
};

/** Converts one observation to points in the vehicle frame (sensorPose applied); returns
 *  false if the observation is not a 3D scan. `source` names the file in error messages. */
bool observationToPoints(const mrpt::obs::CObservation& obs, std::vector<PointXYZI>& out,
                         const RawlogSourceOptions& opts, const std::string& source);

}  // namespace rasterslam::io
