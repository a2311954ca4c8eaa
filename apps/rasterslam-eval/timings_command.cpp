// rasterslam-eval timings: cost per scan and memory of runs, from their timings.csv.
#include <rasterslam/eval/trajectory_plot.h>

#include <algorithm>
#include <array>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "cli.h"

namespace rasterslam_eval_cli
{
namespace
{
// Below the options in --help (the formatter wraps it at 100 columns, keeping line breaks).
const char* kTimingsAbout =
    "Per-scan cost and resident memory of runs: RUN_DIR is the --out folder of rasterslam run "
    "(its timings.csv is read) or a timings.csv itself. Per run:\n"
    "ms per scan: mean of total and of each stage over the first and the last 10 % of the "
    "scans; last / first;\n"
    "rss: resident memory (MB): max over the first 10 %, max over the last 10 %, peak;\n"
    "rss growth: MB per 1000 scans, slope of a least-squares line over the second half;\n"
    "after scan K: with --after-scan, max rss over scans K-100..K, and last 10 % max / it.";

namespace fs = std::filesystem;

// The stage columns summarised; total first.
constexpr std::size_t kStages = 6;
const std::array<const char*, kStages> kStageColumns = {"total_ms",    "read_ms",    "rasterize_ms",
                                                        "odometry_ms", "mapping_ms", "loop_ms"};
constexpr std::size_t kTotal = 0, kLoop = 5;
// Scans before --after-scan K that make its reference figure.
constexpr double kAfterSpan = 100;

struct Run
{
	std::string label, file;
	std::vector<double> index, rss;
	std::array<std::vector<double>, kStages> ms;  //!< in the order of kStageColumns
};

std::vector<std::string> splitCsv(const std::string& line)
{
	std::vector<std::string> out(1);
	for (const char c : line)
	{
		if (c == ',')
			out.emplace_back();
		else
			out.back() += c;
	}
	return out;
}

Run loadRun(const std::string& file, const std::string& label)
{
	std::ifstream in(file);
	if (!in)
		throw std::runtime_error("cannot open '" + file + "'");
	auto where = [&](std::size_t line)
	{ return "'" + file + "' line " + std::to_string(line) + ": "; };
	std::string text;
	std::size_t lineNo = 1;
	if (!std::getline(in, text))
		throw std::runtime_error(where(1) + "empty file, expected the timings.csv header");
	if (!text.empty() && text.back() == '\r')
		text.pop_back();
	// Columns by name, so that added columns do not break old readers.
	const std::vector<std::string> header = splitCsv(text);
	auto column = [&](const std::string& name)
	{
		const auto it = std::find(header.begin(), header.end(), name);
		if (it == header.end())
			throw std::runtime_error(where(1) + "no column '" + name + "' in the header");
		return static_cast<std::size_t>(it - header.begin());
	};
	const std::size_t indexCol = column("index"), rssCol = column("rss_mb");
	std::array<std::size_t, kStages> stageCols{};
	for (std::size_t s = 0; s < kStages; ++s)
		stageCols[s] = column(kStageColumns[s]);

	Run run;
	run.label = label;
	run.file = file;
	while (std::getline(in, text))
	{
		++lineNo;
		if (!text.empty() && text.back() == '\r')
			text.pop_back();
		if (text.empty())
			continue;
		const std::vector<std::string> f = splitCsv(text);
		if (f.size() != header.size())
		{
			throw std::runtime_error(where(lineNo) + std::to_string(f.size()) +
			                         " fields, the header has " + std::to_string(header.size()));
		}
		auto number = [&](std::size_t col)
		{
			char* end = nullptr;
			const double v = std::strtod(f[col].c_str(), &end);
			if (f[col].empty() || *end != '\0' || !std::isfinite(v))
			{
				throw std::runtime_error(where(lineNo) + header[col] +
				                         ": expected a finite number, got '" + f[col] + "'");
			}
			return v;
		};
		const double index = number(indexCol);
		// The fit and the plot take the index as x: scans must come in order.
		if (!run.index.empty() && index <= run.index.back())
		{
			throw std::runtime_error(where(lineNo) + "index " + f[indexCol] +
			                         " is not above the previous scan's " +
			                         numberText(run.index.back()));
		}
		run.index.push_back(index);
		run.rss.push_back(number(rssCol));
		for (std::size_t s = 0; s < kStages; ++s)
			run.ms[s].push_back(number(stageCols[s]));
	}
	if (run.index.empty())
		throw std::runtime_error(where(lineNo) + "no scan after the header");
	return run;
}

double mean(const std::vector<double>& v, std::size_t from, std::size_t to)
{
	double s = 0;
	for (std::size_t i = from; i < to; ++i)
		s += v[i];
	return s / static_cast<double>(to - from);
}

double maxOf(const std::vector<double>& v, std::size_t from, std::size_t to)
{
	return *std::max_element(v.begin() + static_cast<std::ptrdiff_t>(from),
	                         v.begin() + static_cast<std::ptrdiff_t>(to));
}

/** Slope of the least-squares line y(x) over [from, to); NaN when x does not vary. */
double slope(const std::vector<double>& x, const std::vector<double>& y, std::size_t from,
             std::size_t to)
{
	if (to - from < 2)
		return std::nan("");
	const double mx = mean(x, from, to), my = mean(y, from, to);
	double sxy = 0, sxx = 0;
	for (std::size_t i = from; i < to; ++i)
	{
		sxy += (x[i] - mx) * (y[i] - my);
		sxx += (x[i] - mx) * (x[i] - mx);
	}
	return sxx > 0 ? sxy / sxx : std::nan("");
}

struct Summary
{
	std::size_t scans = 0, tenth = 0;
	std::array<double, kStages> first{}, last{};
	double rssFirstMax = 0, rssLastMax = 0, rssPeak = 0;
	double growthPer1000 = 0;  //!< NaN with fewer than 2 scans in the second half
	double afterFrom = 0, afterTo = 0, afterMax = 0;
};

Summary summarize(const Run& r, bool after, double afterScan)
{
	Summary s;
	s.scans = r.index.size();
	// At least one scan, so that short test runs still get figures.
	s.tenth = std::max<std::size_t>(1, s.scans / 10);
	const std::size_t lastFrom = s.scans - s.tenth;
	for (std::size_t k = 0; k < kStages; ++k)
	{
		s.first[k] = mean(r.ms[k], 0, s.tenth);
		s.last[k] = mean(r.ms[k], lastFrom, s.scans);
	}
	s.rssFirstMax = maxOf(r.rss, 0, s.tenth);
	s.rssLastMax = maxOf(r.rss, lastFrom, s.scans);
	s.rssPeak = maxOf(r.rss, 0, s.scans);
	// The second half only: the steady state, without the start-up growth that would steepen
	// the line.
	s.growthPer1000 = 1000.0 * slope(r.index, r.rss, s.scans / 2, s.scans);
	if (after)
	{
		s.afterFrom = std::max(0.0, afterScan - kAfterSpan);
		s.afterTo = afterScan;
		bool any = false;
		for (std::size_t i = 0; i < s.scans; ++i)
		{
			if (r.index[i] >= s.afterFrom && r.index[i] <= s.afterTo)
			{
				s.afterMax = any ? std::max(s.afterMax, r.rss[i]) : r.rss[i];
				any = true;
			}
		}
		if (!any)
		{
			throw std::runtime_error("'" + r.file + "': no scan with index in " +
			                         numberText(s.afterFrom) + ".." + numberText(s.afterTo) +
			                         " (--after-scan)");
		}
	}
	return s;
}

double ratio(double num, double den)
{
	return den != 0 ? num / den : std::nan("");
}

std::string fixed(double v, int decimals)
{
	if (!std::isfinite(v))
		return "-";
	char buf[64];
	std::snprintf(buf, sizeof(buf), "%.*f", decimals, v);
	return buf;
}

/** Centred moving average of `w` samples, fewer at the ends: no lag, so that a slow stretch
 *  lines up with the memory curve above it. */
std::vector<double> movingAverage(const std::vector<double>& v, std::size_t w)
{
	std::vector<double> prefix(v.size() + 1, 0.0), out(v.size());
	for (std::size_t i = 0; i < v.size(); ++i)
		prefix[i + 1] = prefix[i] + v[i];
	for (std::size_t i = 0; i < v.size(); ++i)
	{
		const std::size_t from = i >= w / 2 ? i - w / 2 : 0;
		const std::size_t to = std::min(v.size(), i + w - w / 2);
		out[i] = (prefix[to] - prefix[from]) / static_cast<double>(to - from);
	}
	return out;
}

// ---- plot ----

/** An axis range that starts and ends on a tick of step 1, 2 or 5 times a power of ten. */
struct Axis
{
	double lo = 0, hi = 1, step = 1;
	Axis(double minV, double maxV)
	{
		if (!(maxV > minV))
			maxV = minV + 1;  // flat data: still a readable axis
		step = eval::niceStep(maxV - minV, 5);
		lo = std::floor(minV / step) * step;
		hi = std::ceil(maxV / step) * step;
	}
};

struct Panel
{
	cv::Rect box;
	Axis x, y;
	/** Pixel position in 1/16 px (shift 4 of the OpenCV drawing calls). */
	cv::Point at(double xv, double yv) const
	{
		const double px = box.x + (xv - x.lo) / (x.hi - x.lo) * box.width;
		const double py = box.y + box.height - (yv - y.lo) / (y.hi - y.lo) * box.height;
		return {static_cast<int>(std::lround(px * 16)), static_cast<int>(std::lround(py * 16))};
	}
};
constexpr int kShift = 4;

const auto kFont = cv::FONT_HERSHEY_SIMPLEX;
const cv::Scalar kBlack(0, 0, 0), kGrey(110, 110, 110), kGrid(225, 225, 225);

std::string tickText(double v)
{
	char buf[32];
	std::snprintf(buf, sizeof(buf), "%.10g", std::abs(v) < 1e-9 ? 0.0 : v);
	return buf;
}

void text(cv::Mat& img, const std::string& s, cv::Point at, double scale, cv::Scalar colour,
          double alignX = 0)  // alignX: 0 left, 0.5 centre, 1 right
{
	const cv::Size sz = cv::getTextSize(s, kFont, scale, 1, nullptr);
	cv::putText(img, s, cv::Point(at.x - static_cast<int>(alignX * sz.width), at.y + sz.height / 2),
	            kFont, scale, colour, 1, cv::LINE_AA);
}

void drawFrame(cv::Mat& img, const Panel& p, const std::string& title, bool xLabels)
{
	// Ticks by count: adding up the step would drift off the last tick.
	for (int k = 0; p.x.lo + k * p.x.step <= p.x.hi + p.x.step / 2; ++k)
	{
		const double v = p.x.lo + k * p.x.step;
		cv::line(img, p.at(v, p.y.lo), p.at(v, p.y.hi), kGrid, 1, cv::LINE_8, kShift);
		if (xLabels)
			text(img, tickText(v), cv::Point(p.at(v, p.y.lo).x / 16, p.box.br().y + 16), 0.45,
			     kBlack, 0.5);
	}
	for (int k = 0; p.y.lo + k * p.y.step <= p.y.hi + p.y.step / 2; ++k)
	{
		const double v = p.y.lo + k * p.y.step;
		cv::line(img, p.at(p.x.lo, v), p.at(p.x.hi, v), kGrid, 1, cv::LINE_8, kShift);
		text(img, tickText(v), cv::Point(p.box.x - 8, p.at(p.x.lo, v).y / 16), 0.45, kBlack, 1);
	}
	cv::rectangle(img, p.box, kBlack, 1);
	// putText has no vertical text: the y title stands above the panel.
	text(img, title, cv::Point(p.box.x, p.box.y - 16), 0.55, kBlack);
}

/** The curve in pixels (1/16 px), keeping per pixel column only the first, lowest, highest and
 *  last points: thousands of thick anti-aliased segments in one column smear into beads, while
 *  these four keep every spike and step. */
std::vector<cv::Point> curvePoints(const Panel& p, const std::vector<double>& x,
                                   const std::vector<double>& y)
{
	std::vector<cv::Point> out;
	for (std::size_t from = 0; from < x.size();)
	{
		const int column = p.at(x[from], y[from]).x / 16;
		std::size_t to = from, lo = from, hi = from;
		for (; to < x.size() && p.at(x[to], y[to]).x / 16 == column; ++to)
		{
			lo = y[to] < y[lo] ? to : lo;
			hi = y[to] > y[hi] ? to : hi;
		}
		std::vector<std::size_t> keep = {from, lo, hi, to - 1};
		std::sort(keep.begin(), keep.end());
		keep.erase(std::unique(keep.begin(), keep.end()), keep.end());
		for (const std::size_t i : keep)
			out.push_back(p.at(x[i], y[i]));
		from = to;
	}
	return out;
}

void drawLine(cv::Mat& img, const Panel& p, const std::vector<double>& x,
              const std::vector<double>& y, cv::Scalar colour, bool dashed)
{
	const std::vector<cv::Point> pts = curvePoints(p, x, y);
	if (!dashed)
	{
		cv::polylines(img, pts, false, colour, 2, cv::LINE_AA, kShift);
		return;
	}
	// Dashes by distance along the curve, whatever the spacing of the scans: 7 px on, 5 off.
	const double on = 7 * 16, period = 12 * 16;
	std::vector<std::vector<cv::Point>> dashes(1);
	double travelled = 0;
	for (std::size_t i = 1; i < pts.size(); ++i)
	{
		const cv::Point2d a = pts[i - 1], d = cv::Point2d(pts[i]) - a;
		const double len = std::hypot(d.x, d.y);
		for (double s = 0; s < len;)
		{
			const double phase = std::fmod(travelled + s, period);
			const double step = std::min(len - s, phase < on ? on - phase : period - phase);
			if (phase < on)
			{
				const cv::Point2d u = a + d * (s / len), v = a + d * ((s + step) / len);
				if (dashes.back().empty())
					dashes.back().emplace_back(cvRound(u.x), cvRound(u.y));
				dashes.back().emplace_back(cvRound(v.x), cvRound(v.y));
			}
			else if (!dashes.back().empty())
				dashes.emplace_back();
			s += step;
		}
		travelled += len;
	}
	cv::polylines(img, dashes, false, colour, 2, cv::LINE_AA, kShift);
}

cv::Mat renderPlot(const std::vector<Run>& runs, std::size_t window)
{
	// Matplotlib's first colours, as BGR.
	const std::vector<cv::Scalar> palette = {
	    {180, 119, 31}, {14, 127, 255},  {44, 160, 44},   {40, 39, 214},  {189, 103, 148},
	    {75, 86, 140},  {194, 119, 227}, {127, 127, 127}, {34, 189, 188}, {207, 190, 23}};
	const int width = 1200, height = 800, left = 80, right = 30;
	cv::Mat img(height, width, CV_8UC3, cv::Scalar(255, 255, 255));

	std::vector<std::vector<double>> total(runs.size()), loop(runs.size());
	double maxIndex = 0, rssLo = HUGE_VAL, rssHi = -HUGE_VAL, msHi = 0;
	for (std::size_t r = 0; r < runs.size(); ++r)
	{
		total[r] = movingAverage(runs[r].ms[kTotal], window);
		loop[r] = movingAverage(runs[r].ms[kLoop], window);
		maxIndex = std::max(maxIndex, runs[r].index.back());
		const auto [lo, hi] = std::minmax_element(runs[r].rss.begin(), runs[r].rss.end());
		rssLo = std::min(rssLo, *lo);
		rssHi = std::max(rssHi, *hi);
		msHi = std::max({msHi, *std::max_element(total[r].begin(), total[r].end()),
		                 *std::max_element(loop[r].begin(), loop[r].end())});
	}
	const Axis x(0, maxIndex);
	const Panel rssPanel{cv::Rect(left, 90, width - left - right, 280), x, Axis(rssLo, rssHi)};
	const Panel msPanel{cv::Rect(left, 440, width - left - right, 280), x, Axis(0, msHi)};
	drawFrame(img, rssPanel, "resident memory, MB", false);
	drawFrame(img, msPanel, "ms per scan (moving average of " + std::to_string(window) + ")", true);
	text(img, "scan", cv::Point(left + msPanel.box.width / 2, msPanel.box.br().y + 44), 0.55,
	     kBlack, 0.5);
	// Line styles of the lower panel, in its title row.
	const int ky = msPanel.box.y - 16, kx = msPanel.box.br().x - 300;
	cv::line(img, cv::Point(kx, ky), cv::Point(kx + 30, ky), kGrey, 2, cv::LINE_AA);
	text(img, "total", cv::Point(kx + 38, ky), 0.5, kGrey);
	for (int dx = 150; dx < 180; dx += 12)
		cv::line(img, cv::Point(kx + dx, ky), cv::Point(kx + dx + 7, ky), kGrey, 2, cv::LINE_AA);
	text(img, "loop closure", cv::Point(kx + 188, ky), 0.5, kGrey);

	// Legend: one row across the top; long labels shrink the font rather than get clipped.
	const int sample = 30, gap = 12, spacing = 36;
	int need = 0;
	for (const auto& r : runs)
		need += sample + gap + cv::getTextSize(r.label, kFont, 0.55, 1, nullptr).width + spacing;
	const double scale = std::min(0.55, 0.55 * (width - 2 * left) / std::max(1, need));
	int lx = left;
	for (std::size_t r = 0; r < runs.size(); ++r)
	{
		const cv::Scalar colour = palette[r % palette.size()];
		cv::line(img, cv::Point(lx, 30), cv::Point(lx + sample, 30), colour, 3, cv::LINE_AA);
		text(img, runs[r].label, cv::Point(lx + sample + gap, 30), scale, kBlack);
		lx += sample + gap + cv::getTextSize(runs[r].label, kFont, scale, 1, nullptr).width +
		      static_cast<int>(spacing * scale / 0.55);
	}

	// Dashed lines first: the totals stay on top where the two meet.
	for (std::size_t r = 0; r < runs.size(); ++r)
		drawLine(img, msPanel, runs[r].index, loop[r], palette[r % palette.size()], true);
	for (std::size_t r = 0; r < runs.size(); ++r)
	{
		const cv::Scalar colour = palette[r % palette.size()];
		drawLine(img, rssPanel, runs[r].index, runs[r].rss, colour, false);
		drawLine(img, msPanel, runs[r].index, total[r], colour, false);
	}
	return img;
}

void savePlot(const std::string& path, const cv::Mat& img)
{
	eval::writePng(path, img);
}

/** The run's name when no --label is given: its folder ("runs/a/" and "runs/a/timings.csv"
 *  are both "a"). */
std::string folderName(const std::string& arg, bool isFile)
{
	fs::path p = fs::absolute(arg).lexically_normal();
	if (!p.has_filename())
		p = p.parent_path();
	if (isFile)
		p = p.parent_path();
	return p.filename().string();
}
struct TimingsOptions
{
	std::vector<std::string> dirs, labels;
	std::string plot;
	std::size_t window = 100, afterScan = 0;
	bool after = false;  //!< --after-scan given
	bool json = false;
};

int runTimings(const TimingsOptions& o)
{
	const std::vector<std::string>& dirs = o.dirs;
	const std::vector<std::string>& labels = o.labels;
	const std::size_t window = o.window;
	const bool after = o.after;
	const auto afterScan = static_cast<double>(o.afterScan);

	std::vector<Run> runs;
	std::vector<Summary> sums;
	for (std::size_t i = 0; i < dirs.size(); ++i)
	{
		const bool isFile = fs::is_regular_file(dirs[i]);
		const std::string file = isFile ? dirs[i] : (fs::path(dirs[i]) / "timings.csv").string();
		runs.push_back(loadRun(file, labels.empty() ? folderName(dirs[i], isFile) : labels[i]));
		sums.push_back(summarize(runs.back(), after, afterScan));
	}
	if (!o.plot.empty())
		savePlot(o.plot, renderPlot(runs, window));

	if (o.json)
	{
		Json j;
		j["runs"] = Json::array();
		for (std::size_t i = 0; i < runs.size(); ++i)
		{
			const Summary& s = sums[i];
			Json run;
			run["label"] = runs[i].label;
			run["file"] = runs[i].file;
			run["scans"] = s.scans;
			run["tenth_scans"] = s.tenth;
			for (std::size_t k = 0; k < kStages; ++k)
			{
				run[kStageColumns[k]] = {{"first", jsonNumber(s.first[k])},
				                         {"last", jsonNumber(s.last[k])},
				                         {"ratio", jsonNumber(ratio(s.last[k], s.first[k]))}};
			}
			run["rss_first_max_mb"] = jsonNumber(s.rssFirstMax);
			run["rss_last_max_mb"] = jsonNumber(s.rssLastMax);
			run["rss_peak_mb"] = jsonNumber(s.rssPeak);
			run["rss_growth_mb_per_1000_scans"] = jsonNumber(s.growthPer1000);
			run["after_scan"] = nullptr;
			if (after)
			{
				// Scan numbers are whole: written as integers.
				run["after_scan"] = {{"scan", static_cast<std::uint64_t>(s.afterTo)},
				                     {"from", static_cast<std::uint64_t>(s.afterFrom)},
				                     {"rss_max_mb", jsonNumber(s.afterMax)},
				                     {"last_ratio", jsonNumber(ratio(s.rssLastMax, s.afterMax))}};
			}
			j["runs"].push_back(std::move(run));
		}
		j["window"] = window;
		j["plot"] = o.plot.empty() ? Json(nullptr) : Json(o.plot);
		std::cout << jsonLine(j);
		return 0;
	}

	for (std::size_t i = 0; i < runs.size(); ++i)
	{
		const Summary& s = sums[i];
		const std::size_t n = s.scans;
		std::cout << (i ? "\n" : "") << "run          : " << runs[i].label << " (" << runs[i].file
		          << "), " << n << " scans, 10 % = " << s.tenth << "\n"
		          << "ms per scan  :" << std::setw(12) << "first 10 %" << std::setw(12)
		          << "last 10 %" << std::setw(12) << "last/first"
		          << "\n";
		for (std::size_t k = 0; k < kStages; ++k)
		{
			const std::string stage(kStageColumns[k], std::strlen(kStageColumns[k]) - 3);
			std::cout << "  " << std::left << std::setw(11) << stage << ":" << std::right
			          << std::setw(12) << fixed(s.first[k], 3) << std::setw(12)
			          << fixed(s.last[k], 3) << std::setw(12)
			          << fixed(ratio(s.last[k], s.first[k]), 3) << "\n";
		}
		std::cout << "rss, MB      : max " << fixed(s.rssFirstMax, 1) << " in the first 10 %, max "
		          << fixed(s.rssLastMax, 1) << " in the last 10 %, peak " << fixed(s.rssPeak, 1)
		          << "\n"
		          << "rss growth   : " << fixed(s.growthPer1000, 3)
		          << " MB per 1000 scans (least squares over scans "
		          << numberText(runs[i].index[n / 2]) << ".." << numberText(runs[i].index.back())
		          << ")\n";
		if (after)
		{
			std::cout << "after scan   : max " << fixed(s.afterMax, 1) << " MB over scans "
			          << numberText(s.afterFrom) << ".." << numberText(s.afterTo)
			          << "; last 10 % / after scan " << numberText(s.afterTo) << " = "
			          << fixed(ratio(s.rssLastMax, s.afterMax), 3) << "\n";
		}
	}
	if (!o.plot.empty())
		std::cout << "\nplot         : " << o.plot << "\n";
	return 0;
}

}  // namespace

Command addTimings(CLI::App& app)
{
	CLI::App* sub = cli::subcommand(app, "timings",
	                                "cost per scan and memory of runs (timings.csv), and a plot",
	                                kTimingsAbout);
	auto o = std::make_shared<TimingsOptions>();
	sub->add_option("RUN_DIR", o->dirs, "run folders (rasterslam run --out) or timings.csv files")
	    ->required()
	    ->check(cli::unnamed(CLI::ExistingPath))
	    ->type_name("");
	// One value each time: "--label a DIR" leaves DIR to RUN_DIR.
	sub->add_option("--label", o->labels,
	                "name of a run in the text, JSON and plot; once per RUN_DIR, in the same order "
	                "(default: the folder name)")
	    ->allow_extra_args(false)
	    ->type_name("NAME");
	CLI::Option* after =
	    sub->add_option("--after-scan", o->afterScan,
	                    "also report the memory after scan K (e.g. the end of a lap)")
	        ->check(wholeNumber(0, 1000000000))
	        ->type_name("K");
	sub->add_option("--plot", o->plot,
	                "write a PNG: rss per scan above, ms per scan below (total solid, loop "
	                "closure dashed)")
	    ->check(outputFile())
	    ->type_name("FILE");
	sub->add_option("--window", o->window, "scans of the plot's moving average of ms per scan")
	    ->check(wholeNumber(1, 1000000000))
	    ->type_name("N")
	    ->capture_default_str();
	sub->add_flag("--json", o->json, "print one JSON object instead of text");
	return {sub, [o, after]
	        {
		        o->after = after->count() > 0;
		        // Checks CLI11 cannot express, before reading any file.
		        if (!o->labels.empty() && o->labels.size() != o->dirs.size())
		        {
			        cli::usageError("rasterslam-eval timings",
			                        "give --label once per RUN_DIR (RUN_DIR: " +
			                            std::to_string(o->dirs.size()) +
			                            ", --label: " + std::to_string(o->labels.size()) + ")");
		        }
		        return runTimings(*o);
	        }};
}

}  // namespace rasterslam_eval_cli
