// The record of every processed scan, in memory or in an unnamed temporary file.
#pragma once

#include <mrpt/graphs/TNodeID.h>
#include <mrpt/math/TPose3D.h>
#include <rasterslam/core/plugin.h>

#include <cstddef>
#include <functional>
#include <optional>
#include <string>
#include <vector>

namespace rasterslam
{
/** Milliseconds spent in each stage for one scan. */
struct StageTimes
{
	double read = 0, rasterize = 0, odometry = 0, mapping = 0, loop = 0, total = 0;
};

/** What the engine knows of every input scan. */
struct ScanRecord
{
	std::size_t index = 0;
	double stamp = 0;
	std::size_t numPoints = 0;
	TrackingStatus status = TrackingStatus::Initializing;
	std::size_t inliers = 0;
	bool keyframe = false;
	bool late = false;                 //!< --realtime: started after its due time
	mrpt::graphs::TNodeID kfNode = 0;  //!< keyframe the scan is attached to
	// Poses as plain TPose3D (48 bytes, against 136 for a CPose3D with its cached rotation):
	// a record is kept for every scan of a run, hours of them in a lifelong one.
	mrpt::math::TPose3D T_kf_scan;  //!< its pose in the frame of that keyframe
	/** The pose the scan had when it was processed (what a robot would have acted on). */
	mrpt::math::TPose3D onlinePose;
	StageTimes ms;
	float rssMb = 0;  //!< resident memory of the process after the scan, MB
	std::optional<mrpt::math::TPose3D> groundTruth;
};

/** Opens an unnamed temporary file for reading and writing in `dir`, or else in $TMPDIR, or
 *  else in /tmp (not std::tmpfile(): glibc's ignores TMPDIR, and /tmp is often a RAM disk).
 *  The name is removed at once, so the system deletes the file however the process ends.
 *  Returns its descriptor; throws, naming the folder and `what` it was for, when none can be
 *  made. */
int openUnnamedTempFile(const std::string& dir, const std::string& what);

/** Every processed scan's record, in the order added. By default in memory; spooled() keeps
 *  them in an unnamed temporary file instead (264 bytes a scan that a lifelong run no longer
 *  holds in memory), with the last few hundred buffered. Not thread-safe: one thread adds
 *  and reads. A write that fails (a full disk) is kept as error(), not thrown: the records
 *  from there on are lost, and reading any record from the file throws that error. */
class ScanLog
{
   public:
	ScanLog() = default;  //!< in memory
	/** In an unnamed temporary file (see openUnnamedTempFile()); throws when none can be made. */
	static ScanLog spooled(const std::string& dir = {});
	/** In the file open for reading and writing as `fd`, which the log closes at the end. */
	static ScanLog onDescriptor(int fd);
	ScanLog(ScanLog&& o) noexcept;
	ScanLog& operator=(ScanLog&& o) noexcept;
	ScanLog(const ScanLog&) = delete;
	ScanLog& operator=(const ScanLog&) = delete;
	~ScanLog();

	void push_back(const ScanRecord& r);
	std::size_t size() const { return size_; }
	bool empty() const { return size_ == 0; }
	bool isSpooled() const { return fd_ >= 0; }
	/** A copy of record i; throws std::out_of_range past the end, std::runtime_error if the
	 *  record was lost or cannot be read back. */
	ScanRecord operator[](std::size_t i) const;
	ScanRecord front() const { return (*this)[0]; }
	ScanRecord back() const { return (*this)[size_ - 1]; }
	/** Changes record i in place (read, `f`, written back). */
	void modify(std::size_t i, const std::function<void(ScanRecord&)>& f);
	/** Calls `f` with every record in order (read back in chunks when spooled). */
	void forEach(const std::function<void(const ScanRecord&)>& f) const;
	/** Empty, or why records were lost: the first failed write, with the system's reason. */
	const std::string& error() const { return error_; }

   private:
	void flushPending();
	void readSpooled(std::size_t first, std::size_t n, ScanRecord* out) const;

	std::vector<ScanRecord> mem_;  //!< in memory: all; spooled: those not written yet
	std::size_t size_ = 0;         //!< records added
	std::size_t written_ = 0;      //!< spooled: records in the file
	int fd_ = -1;
	std::string error_;
};

}  // namespace rasterslam
