// The files a run leaves in its output folder.
#pragma once

#include <mrpt/containers/yaml.h>
#include <rasterslam/core/engine.h>
#include <rasterslam/core/pose_conversions.h>

#include <Eigen/Geometry>
#include <cstdio>
#include <functional>
#include <string>
#include <vector>

namespace rasterslam::io
{
using rasterslam::toIsometry;  // Eigen isometry of an MRPT pose (core/pose_conversions.h)

/** Loop decisions written out as a run makes them (RunOptions::onLoopDecisions) to an
 *  unnamed temporary file, which the system removes whatever happens: a lifelong run keeps
 *  none of them in memory, and writeRunOutputs copies them into loops.txt at the end. */
class LoopDecisionSpool
{
   public:
	/** An unnamed temporary file in `dir`, or else in $TMPDIR, or else in /tmp (the system
	 *  removes it however the process ends). Throws, naming the folder, when none can be made. */
	explicit LoopDecisionSpool(const std::string& dir = {});
	/** Spools to `f`, opened for reading and writing, and closes it at the end. */
	explicit LoopDecisionSpool(std::FILE* f);
	~LoopDecisionSpool();
	LoopDecisionSpool(const LoopDecisionSpool&) = delete;
	LoopDecisionSpool& operator=(const LoopDecisionSpool&) = delete;
	/** Appends their loops.txt lines. A write error is kept, not thrown (this runs on the back
	 *  end's thread): finish() reports it and copyTo() throws it. */
	void append(const std::vector<LoopDecision>& decisions);
	std::size_t size() const { return lines_; }  //!< decisions appended
	/** Flushes what is buffered. Returns why the spool lost lines (a failed write, with the
	 *  system's reason) or an empty string when every line is kept. Call it once the back end has
	 *  stopped, before copyTo(): a caller can then still write the run's other outputs. */
	std::string finish();
	/** Every line appended so far, in order, added to `buf` in chunks (`flush` after each). */
	void copyTo(std::string& buf, const std::function<void()>& flush) const;

   private:
	std::FILE* f_ = nullptr;
	std::size_t lines_ = 0;
	bool failed_ = false;
	int errno_ = 0;  //!< the system's reason for the first failed write
};

/** A loop decision as its loops.txt line (newline included). */
void appendLoopLine(std::string& buf, const LoopDecision& l);

/** Writes into `dir` (every file through a temporary name and a rename):
 *  - trajectory.tum, trajectory.kitti: one pose per processed scan;
 *  - groundtruth.tum, groundtruth.kitti: when every processed scan had ground truth;
 *  - timings.csv: per-scan stage times (ms), status, inliers, keyframe flag;
 *  - loops.txt: every loop candidate examined, when a loop detector ran (those in
 *    `spooledLoops` first, then res.loopDecisions);
 *  - pose_graph.graph: the keyframe pose graph in MRPT's text format (opens in MRPT tools);
 *  - run.yaml: `runInfo` as given (config, versions, input, counts, summary). */
void writeRunOutputs(const std::string& dir, const RunResult& res,
                     const mrpt::containers::yaml& runInfo,
                     const LoopDecisionSpool* spooledLoops = nullptr);

/** Checks that `dir` exists or can be created and that a file can be written in it; throws
 *  naming the folder otherwise. */
void ensureWritableDir(const std::string& dir);

}  // namespace rasterslam::io
