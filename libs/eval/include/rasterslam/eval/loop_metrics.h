// Loop-closure metrics: precision and recall of the loop detector's decisions (loops.txt)
// against a ground-truth trajectory, a sweep of the score threshold and its PR plot.
#pragma once

#include <rasterslam/io/trajectory_io.h>

#include <Eigen/Geometry>
#include <cstddef>
#include <istream>
#include <limits>
#include <opencv2/core/mat.hpp>
#include <string>
#include <vector>

namespace rasterslam::eval
{
/** One line of loops.txt: a candidate the loop detector examined for a query keyframe. */
struct LoopCandidate
{
	double queryStamp = 0;
	/** Stamp of the matched keyframe of the candidate map; negative (-1) when none matched. */
	double candidateStamp = -1;
	double score = 0;  //!< normalized BOW score
	std::size_t inliers = 0;
	bool verified = false;  //!< the geometric check passed
	bool accepted = false;  //!< became a loop edge
	std::string reason;
	/** Pose of the query in the candidate keyframe's frame (identity when none). */
	Eigen::Isometry3d T_candidate_query = Eigen::Isometry3d::Identity();
	std::size_t line = 0;  //!< line number in the file, for messages

	bool hasCandidate() const { return candidateStamp >= 0; }
};

/** The lines of one loops.txt and the name to quote in messages. */
struct LoopLog
{
	std::string source;
	std::vector<LoopCandidate> candidates;
};

/** Reads loops.txt ("query_stamp candidate_stamp score inliers verified accepted reason x y z
 *  qx qy qz qw"; '#' lines and blank lines skipped). Throws std::runtime_error naming the file
 *  and line on a malformed line. `source` is the name used in messages. */
LoopLog parseLoopLog(std::istream& in, const std::string& source);
LoopLog loadLoopLog(const std::string& path);

struct LoopEvalParams
{
	/** A detection is correct when the two places are at most this far apart. */
	double distance_m = 4.0;
	/** Places less than this much older than the query are not loop closures (the vehicle is
	 *  simply still there): they make no positive and their detections are ignored. */
	double exclude_s = 30.0;
	/** Largest difference between a loops.txt stamp and the nearest ground-truth stamp. */
	double maxDt = 0.02;
	/** A verified line (one with a registration) is judged by its registration instead: it is
	 *  correct when its pose of the query in the candidate's frame is within registration_m
	 *  and registration_deg of the ground truth's, however far apart the places are (a
	 *  correct registration proves that the two scans overlap), and its query then counts as
	 *  a positive. 0 judges every line by distance_m alone. */
	double registration_m = 1.0;
	double registration_deg = 5.0;
};

/** Counts and rates at one decision rule. */
struct PrPoint
{
	double threshold = std::numeric_limits<double>::infinity();
	std::size_t tp = 0, fp = 0, fn = 0;
	double precision = 1;  //!< tp / (tp + fp); 1 when there is no detection
	double recall = 0;     //!< tp / positives; meaningless when !valid
	double f1 = 0;         //!< 2PR / (P + R), 0 when both are 0; meaningless when !valid
	bool valid = false;    //!< recall and F1 are defined (there are positives)
};

struct LoopEvalResult
{
	std::size_t lines = 0;      //!< candidate lines in the file
	std::size_t queries = 0;    //!< distinct query stamps
	std::size_t positives = 0;  //!< queries with an old enough ground-truth place nearby
	/** Candidate lines ignored because the candidate is less than exclude_s older than the
	 *  query; acceptedRecent of them were accepted (a detector bug worth seeing). */
	std::size_t recentLines = 0, acceptedRecent = 0;
	/** Accepted lines (loop edges) and how many of them are wrong (registration off, or
	 *  places farther apart than distance_m when judged by distance): every one of those is
	 *  a wrong edge in the pose graph. */
	std::size_t acceptedLines = 0, acceptedWrong = 0;
	/** Verified lines judged by their registration, and how many of those were correct
	 *  farther than distance_m apart (the revisits a distance test would call wrong). */
	std::size_t registeredLines = 0, registeredFar = 0;
	/** The detector's own decision: per query, its highest-scoring accepted line. */
	PrPoint detector;
	/** Per query, its highest-scoring verified line with score >= threshold; one row per
	 *  distinct score of the file and +inf, by increasing threshold. */
	std::vector<PrPoint> sweep;
	/** Index in `sweep` of the largest F1 (ties: higher precision, then higher threshold);
	 *  npos when no row is valid (no positives). */
	std::size_t best = npos;
	static constexpr std::size_t npos = static_cast<std::size_t>(-1);
};

/** Evaluates the log against the ground truth (any order of stamps). Every stamp of a line
 *  must have a ground-truth pose within maxDt, else std::runtime_error names the stamp, the
 *  file and the line. A query is positive when a ground-truth pose at least exclude_s older than
 *  it lies within distance_m of it, or (registration_m > 0) one of its old enough candidates
 *  is registered correctly; every ground-truth pose counts as a place. */
LoopEvalResult evaluateLoops(const LoopLog& log, const io::Trajectory& groundTruth,
                             const LoopEvalParams& params = {});

/** "threshold,precision,recall,f1,tp,fp,fn" then one row per sweep entry ("inf" for the last
 *  threshold, "nan" for undefined recall and F1). */
std::string loopSweepCsv(const LoopEvalResult& r);

/** Precision (y) over recall (x) of the sweep with the detector's operating point (red) and
 *  the F1 maximum (blue) marked; BGR, 8 bits. */
cv::Mat renderLoopPrPlot(const LoopEvalResult& r, const std::string& title, int width = 800,
                         int height = 600);
/** Writes the plot as PNG through a temporary file and a rename; throws naming the file. */
void saveLoopPrPlot(const std::string& path, const LoopEvalResult& r, const std::string& title);

}  // namespace rasterslam::eval
