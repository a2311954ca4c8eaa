// Loop-closure precision/recall against ground truth, the score-threshold sweep, its plot.
#include <rasterslam/eval/loop_metrics.h>
#include <rasterslam/eval/trajectory_plot.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <numeric>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>
#include <stdexcept>

namespace rasterslam::eval
{
namespace
{
constexpr std::size_t kColumns = 14;
// Scores of loops.txt carry 6 decimals: a tolerance this small only absorbs round-off.
constexpr double kEps = 1e-12;

std::string where(const std::string& source, std::size_t line)
{
	return "'" + source + "' line " + std::to_string(line) + ": ";
}

std::string fmt(const char* f, double v)
{
	char buf[64];
	std::snprintf(buf, sizeof(buf), f, v);
	return buf;
}

double parseDouble(const std::string& tok, const char* column, const std::string& source,
                   std::size_t line)
{
	char* end = nullptr;
	const double v = std::strtod(tok.c_str(), &end);
	if (tok.empty() || *end != '\0' || !std::isfinite(v))
	{
		throw std::runtime_error(where(source, line) + column +
		                         ": expected a finite number, got '" + tok + "'");
	}
	return v;
}

bool parseFlag(const std::string& tok, const char* column, const std::string& source,
               std::size_t line)
{
	if (tok == "0" || tok == "1")
		return tok == "1";
	throw std::runtime_error(where(source, line) + column + ": expected 0 or 1, got '" + tok + "'");
}

/** Ground-truth positions sorted by stamp, for nearest-stamp look-ups. */
class GroundTruthIndex
{
   public:
	GroundTruthIndex(const io::Trajectory& gt, double maxDt) : maxDt_(maxDt)
	{
		std::vector<std::size_t> order(gt.size());
		std::iota(order.begin(), order.end(), std::size_t{0});
		std::stable_sort(order.begin(), order.end(),
		                 [&](std::size_t i, std::size_t j) { return gt[i].stamp < gt[j].stamp; });
		for (const std::size_t i : order)
		{
			stamps_.push_back(gt[i].stamp);
			positions_.push_back(gt[i].pose.translation());
			poses_.push_back(gt[i].pose);
		}
	}

	/** Index of the nearest stamp; throws when it is farther than maxDt. */
	std::size_t find(double t, const char* what, const LoopLog& log, std::size_t line) const
	{
		const auto it = std::lower_bound(stamps_.begin(), stamps_.end(), t);
		std::size_t best = stamps_.size();
		double bestDt = std::numeric_limits<double>::infinity();
		if (it != stamps_.end())
		{
			best = static_cast<std::size_t>(it - stamps_.begin());
			bestDt = *it - t;
		}
		if (it != stamps_.begin() && t - *std::prev(it) < bestDt)
		{
			best = static_cast<std::size_t>(std::prev(it) - stamps_.begin());
			bestDt = t - *std::prev(it);
		}
		if (best == stamps_.size() || bestDt > maxDt_)
		{
			std::string msg = where(log.source, line) + what + " " + fmt("%.6f", t) +
			                  " has no ground-truth pose within " + fmt("%g", maxDt_) + " s";
			if (best != stamps_.size())
				msg += " (nearest ground-truth stamp " + fmt("%.6f", stamps_[best]) + ")";
			throw std::runtime_error(msg);
		}
		return best;
	}

	double stamp(std::size_t i) const { return stamps_[i]; }
	const Eigen::Vector3d& position(std::size_t i) const { return positions_[i]; }
	const Eigen::Isometry3d& pose(std::size_t i) const { return poses_[i]; }

	/** True when a pose at least excludeS older than `t` lies within distance of `p`. */
	bool hasOldPlaceNear(double t, const Eigen::Vector3d& p, double excludeS, double distance) const
	{
		const double d2 = distance * distance;
		// The same expression as the recency test of a candidate, so round-off cannot make a
		// correct old detection belong to a query that is not a positive.
		for (std::size_t i = 0; i < stamps_.size() && t - stamps_[i] >= excludeS; ++i)
		{
			if ((positions_[i] - p).squaredNorm() <= d2)
				return true;
		}
		return false;
	}

   private:
	double maxDt_;
	std::vector<double> stamps_;
	std::vector<Eigen::Vector3d> positions_;
	std::vector<Eigen::Isometry3d> poses_;
};

PrPoint makePoint(double threshold, std::size_t tp, std::size_t fp, std::size_t positives)
{
	PrPoint p;
	p.threshold = threshold;
	p.tp = tp;
	p.fp = fp;
	p.fn = positives - tp;  // a correct detection implies a positive query, so tp <= positives
	p.precision = tp + fp ? static_cast<double>(tp) / static_cast<double>(tp + fp) : 1.0;
	p.valid = positives > 0;
	if (p.valid)
	{
		p.recall = static_cast<double>(tp) / static_cast<double>(positives);
		const double s = p.precision + p.recall;
		p.f1 = s > 0 ? 2 * p.precision * p.recall / s : 0.0;
	}
	return p;
}

/** The best line of a query under one rule; `score` is -inf while there is none. */
struct Detection
{
	double score = -std::numeric_limits<double>::infinity();
	bool correct = false;
	bool exists() const { return std::isfinite(score); }
};

struct Query
{
	double stamp = 0;
	std::size_t gt = 0;
	Detection verified, accepted;
	bool registeredOld = false;  //!< an old enough candidate was registered correctly
};
}  // namespace

LoopLog parseLoopLog(std::istream& in, const std::string& source)
{
	LoopLog log;
	log.source = source;
	std::string text;
	std::size_t lineNo = 0;
	while (std::getline(in, text))
	{
		++lineNo;
		const auto first = text.find_first_not_of(" \t\r");
		if (first == std::string::npos || text[first] == '#')
			continue;
		std::istringstream ss(text);
		std::vector<std::string> tok;
		for (std::string t; ss >> t;)
			tok.push_back(t);
		if (tok.size() != kColumns)
		{
			throw std::runtime_error(
			    where(source, lineNo) + "expected " + std::to_string(kColumns) +
			    " columns (query_stamp candidate_stamp score inliers verified accepted reason x y "
			    "z qx qy qz qw), got " +
			    std::to_string(tok.size()));
		}
		LoopCandidate c;
		c.line = lineNo;
		c.queryStamp = parseDouble(tok[0], "query_stamp", source, lineNo);
		c.candidateStamp = parseDouble(tok[1], "candidate_stamp", source, lineNo);
		c.score = parseDouble(tok[2], "score", source, lineNo);
		const double inl = parseDouble(tok[3], "inliers", source, lineNo);
		if (inl < 0 || inl != std::floor(inl))
		{
			throw std::runtime_error(where(source, lineNo) +
			                         "inliers: expected a whole number >= 0, got '" + tok[3] + "'");
		}
		c.inliers = static_cast<std::size_t>(inl);
		c.verified = parseFlag(tok[4], "verified", source, lineNo);
		c.accepted = parseFlag(tok[5], "accepted", source, lineNo);
		c.reason = tok[6];
		double v[7];
		static const char* const names[7] = {"x", "y", "z", "qx", "qy", "qz", "qw"};
		for (int k = 0; k < 7; ++k)
			v[k] = parseDouble(tok[7 + k], names[k], source, lineNo);
		const Eigen::Quaterniond q(v[6], v[3], v[4], v[5]);
		// "None" is written as zeros, so a null quaternion means identity, not an error.
		if (q.norm() > 1e-9)
			c.T_candidate_query.linear() = q.normalized().toRotationMatrix();
		c.T_candidate_query.translation() = Eigen::Vector3d(v[0], v[1], v[2]);
		log.candidates.push_back(std::move(c));
	}
	if (in.bad())
		throw std::runtime_error("error reading loop file '" + source + "'");
	return log;
}

LoopLog loadLoopLog(const std::string& path)
{
	std::ifstream in(path);
	if (!in)
		throw std::runtime_error("cannot open loop file '" + path + "'");
	return parseLoopLog(in, path);
}

LoopEvalResult evaluateLoops(const LoopLog& log, const io::Trajectory& groundTruth,
                             const LoopEvalParams& params)
{
	if (groundTruth.empty())
		throw std::runtime_error("the ground truth has no poses");
	const GroundTruthIndex gt(groundTruth, params.maxDt);
	const double d2 = params.distance_m * params.distance_m;

	LoopEvalResult r;
	r.lines = log.candidates.size();
	std::vector<Query> queries;
	std::map<double, std::size_t> queryIndex;
	std::vector<double> scores;
	for (const auto& c : log.candidates)
	{
		scores.push_back(c.score);
		auto [it, added] = queryIndex.try_emplace(c.queryStamp, queries.size());
		if (added)
		{
			Query q;
			q.stamp = c.queryStamp;
			q.gt = gt.find(c.queryStamp, "query stamp", log, c.line);
			queries.push_back(q);
		}
		Query& q = queries[it->second];
		if (!c.hasCandidate())
			continue;
		const std::size_t cg = gt.find(c.candidateStamp, "candidate stamp", log, c.line);
		const bool near = (gt.position(cg) - gt.position(q.gt)).squaredNorm() <= d2;
		bool correct = near;
		const bool byRegistration = params.registration_m > 0 && c.verified;
		if (byRegistration)
		{
			const Eigen::Isometry3d truth = gt.pose(cg).inverse() * gt.pose(q.gt);
			const Eigen::Isometry3d E = truth.inverse() * c.T_candidate_query;
			correct = E.translation().norm() <= params.registration_m &&
			          Eigen::AngleAxisd(E.linear()).angle() * 180 / M_PI <= params.registration_deg;
			++r.registeredLines;
			r.registeredFar += correct && !near;
		}
		if (c.accepted)
		{
			++r.acceptedLines;
			if (!correct)
				++r.acceptedWrong;
		}
		// A match with the place the vehicle has just left is no loop closure, right or wrong.
		// Ground-truth stamps, as for the positives, so that a correct detection that is old
		// enough always makes its query a positive.
		if (!(gt.stamp(q.gt) - gt.stamp(cg) >= params.exclude_s))
		{
			++r.recentLines;
			if (c.accepted)
				++r.acceptedRecent;
			continue;
		}
		// Strictly greater: on equal scores the first line of the file wins, as a detector
		// scanning its candidates in order would keep it.
		if (byRegistration && correct)
			q.registeredOld = true;
		if (c.verified && c.score > q.verified.score)
			q.verified = {c.score, correct};
		if (c.accepted && c.score > q.accepted.score)
			q.accepted = {c.score, correct};
	}
	r.queries = queries.size();
	for (const auto& q : queries)
	{
		if (q.registeredOld || gt.hasOldPlaceNear(gt.stamp(q.gt), gt.position(q.gt),
		                                          params.exclude_s, params.distance_m))
			++r.positives;
	}

	std::size_t tp = 0, fp = 0;
	for (const auto& q : queries)
	{
		if (q.accepted.exists())
			++(q.accepted.correct ? tp : fp);
	}
	r.detector = makePoint(std::numeric_limits<double>::quiet_NaN(), tp, fp, r.positives);

	// Each query's detection at threshold tau is its best verified line if that scores >= tau,
	// so sweeping the thresholds downwards only ever adds detections.
	std::vector<Detection> best;
	for (const auto& q : queries)
	{
		if (q.verified.exists())
			best.push_back(q.verified);
	}
	std::sort(best.begin(), best.end(),
	          [](const Detection& a, const Detection& b) { return a.score > b.score; });
	std::sort(scores.begin(), scores.end());
	scores.erase(std::unique(scores.begin(), scores.end()), scores.end());
	scores.push_back(std::numeric_limits<double>::infinity());
	r.sweep.resize(scores.size());
	tp = fp = 0;
	std::size_t k = 0;
	for (std::size_t i = scores.size(); i-- > 0;)
	{
		for (; k < best.size() && best[k].score >= scores[i]; ++k)
			++(best[k].correct ? tp : fp);
		r.sweep[i] = makePoint(scores[i], tp, fp, r.positives);
	}

	for (std::size_t i = 0; i < r.sweep.size(); ++i)
	{
		const PrPoint& p = r.sweep[i];
		if (!p.valid)
			continue;
		if (r.best == LoopEvalResult::npos)
		{
			r.best = i;
			continue;
		}
		const PrPoint& b = r.sweep[r.best];
		// Ascending thresholds: a full tie goes to the later, more conservative threshold.
		if (p.f1 > b.f1 + kEps ||
		    (std::abs(p.f1 - b.f1) <= kEps && p.precision >= b.precision - kEps))
			r.best = i;
	}
	return r;
}

std::string loopSweepCsv(const LoopEvalResult& r)
{
	std::string out = "threshold,precision,recall,f1,tp,fp,fn\n";
	char buf[256];
	for (const auto& p : r.sweep)
	{
		const std::string thr = std::isinf(p.threshold) ? "inf" : fmt("%.9g", p.threshold);
		const std::string rec = p.valid ? fmt("%.6f", p.recall) : "nan";
		const std::string f1 = p.valid ? fmt("%.6f", p.f1) : "nan";
		std::snprintf(buf, sizeof(buf), "%s,%.6f,%s,%s,%zu,%zu,%zu\n", thr.c_str(), p.precision,
		              rec.c_str(), f1.c_str(), p.tp, p.fp, p.fn);
		out += buf;
	}
	return out;
}

cv::Mat renderLoopPrPlot(const LoopEvalResult& r, const std::string& title, int width, int height)
{
	width = std::max(width, 320);
	height = std::max(height, 260);
	cv::Mat img(height, width, CV_8UC3, cv::Scalar(255, 255, 255));
	const int left = 70, right = 30, top = 62, bottom = 95;
	const int pw = width - left - right, ph = height - top - bottom;
	auto toPx = [&](double recall, double precision)
	{
		return cv::Point(
		    left + static_cast<int>(std::lround(std::clamp(recall, 0.0, 1.0) * pw)),
		    top + static_cast<int>(std::lround((1.0 - std::clamp(precision, 0.0, 1.0)) * ph)));
	};
	const auto font = cv::FONT_HERSHEY_SIMPLEX;
	const cv::Scalar black(0, 0, 0), grid(225, 225, 225), red(0, 0, 220), blue(200, 80, 0),
	    curve(40, 40, 40);
	auto centered = [&](const std::string& s, cv::Point at, double scale, int thick)
	{
		int base = 0;
		const cv::Size sz = cv::getTextSize(s, font, scale, thick, &base);
		cv::putText(img, s, cv::Point(at.x - sz.width / 2, at.y + sz.height / 2), font, scale,
		            black, thick, cv::LINE_AA);
	};

	for (int k = 0; k <= 10; ++k)
	{
		const double v = k / 10.0;
		cv::line(img, toPx(v, 0), toPx(v, 1), grid, 1);
		cv::line(img, toPx(0, v), toPx(1, v), grid, 1);
	}
	cv::rectangle(img, toPx(0, 1), toPx(1, 0), black, 1);
	for (int k = 0; k <= 5; ++k)
	{
		const double v = k / 5.0;
		const std::string label = fmt("%.1f", v);
		cv::line(img, toPx(v, 0), toPx(v, 0) + cv::Point(0, 6), black, 1);
		centered(label, toPx(v, 0) + cv::Point(0, 18), 0.45, 1);
		cv::line(img, toPx(0, v), toPx(0, v) - cv::Point(6, 0), black, 1);
		centered(label, toPx(0, v) - cv::Point(25, 0), 0.45, 1);
	}
	centered("recall", cv::Point(left + pw / 2, top + ph + 42), 0.55, 1);
	// Vertical text is not available in putText: the y label stands above the axis.
	cv::putText(img, "precision", cv::Point(8, top - 14), font, 0.5, black, 1, cv::LINE_AA);
	// Run folder names can be long: shrink the title rather than clip it.
	const double titleScale = std::min(
	    0.6, 0.6 * (width - 20) / std::max(1, cv::getTextSize(title, font, 0.6, 1, nullptr).width));
	centered(title, cv::Point(width / 2, 20), titleScale, 1);

	const bool anyValid = !r.sweep.empty() && r.sweep.front().valid;
	if (!anyValid)
	{
		centered("no positive query: recall undefined", cv::Point(left + pw / 2, top + ph / 2), 0.6,
		         1);
		return img;
	}
	for (std::size_t i = 1; i < r.sweep.size(); ++i)
	{
		const auto& a = r.sweep[i - 1];
		const auto& b = r.sweep[i];
		cv::line(img, toPx(a.recall, a.precision), toPx(b.recall, b.precision), curve, 2,
		         cv::LINE_AA);
	}
	for (const auto& p : r.sweep)
		cv::circle(img, toPx(p.recall, p.precision), 2, curve, cv::FILLED, cv::LINE_AA);

	std::string legendBest;
	if (r.best != LoopEvalResult::npos)
	{
		const auto& b = r.sweep[r.best];
		cv::circle(img, toPx(b.recall, b.precision), 7, blue, 2, cv::LINE_AA);
		legendBest = "F1 max " + fmt("%.3f", b.f1) + " at score >= " +
		             (std::isinf(b.threshold) ? std::string("inf") : fmt("%.4g", b.threshold));
	}
	const auto& d = r.detector;
	const cv::Point dp = toPx(d.recall, d.precision);
	cv::line(img, dp - cv::Point(7, 7), dp + cv::Point(7, 7), red, 2, cv::LINE_AA);
	cv::line(img, dp - cv::Point(7, -7), dp + cv::Point(7, -7), red, 2, cv::LINE_AA);
	const std::string legendDet =
	    "detector: P " + fmt("%.3f", d.precision) + ", R " + fmt("%.3f", d.recall);

	const int ly = top + ph + 72;
	cv::line(img, cv::Point(left, ly - 7), cv::Point(left + 14, ly + 7), red, 2, cv::LINE_AA);
	cv::line(img, cv::Point(left, ly + 7), cv::Point(left + 14, ly - 7), red, 2, cv::LINE_AA);
	cv::putText(img, legendDet, cv::Point(left + 22, ly + 5), font, 0.45, black, 1, cv::LINE_AA);
	if (!legendBest.empty())
	{
		const int lx = left + pw / 2;
		cv::circle(img, cv::Point(lx + 7, ly), 7, blue, 2, cv::LINE_AA);
		cv::putText(img, legendBest, cv::Point(lx + 22, ly + 5), font, 0.45, black, 1, cv::LINE_AA);
	}
	return img;
}

void saveLoopPrPlot(const std::string& path, const LoopEvalResult& r, const std::string& title)
{
	writePng(path, renderLoopPrPlot(r, title));
}

}  // namespace rasterslam::eval
