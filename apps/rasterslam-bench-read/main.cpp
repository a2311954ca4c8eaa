// rasterslam-bench-read: ms per scan to read scans into points, by input: KITTI .bin files and
// MRPT rawlogs (plain or gzip), each converted to the project's point type as in a run. The
// lifelong-tracking issue asks that what kitti2rawlog and rasterslam-sim write by default read
// in at most twice the time of the raw .bin files; this program measures both in one process.
#include <rasterslam/cli/app.h>
#include <rasterslam/io/kitti.h>
#include <rasterslam/io/rawlog_source.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

using namespace rasterslam;
namespace fs = std::filesystem;

namespace
{
using Clock = std::chrono::steady_clock;
double msSince(Clock::time_point t0)
{
	return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

struct Result
{
	std::string label;
	double megabytes = 0;
	std::size_t scans = 0;
	double points = 0;  // a scan, mean
	double median = 0, p95 = 0;
};

double quantile(std::vector<double> v, double q)
{
	if (v.empty())
		return 0;
	std::sort(v.begin(), v.end());
	return v[std::min(v.size() - 1, static_cast<std::size_t>(q * static_cast<double>(v.size())))];
}

/** Times `passes` passes of readAll (the first warms the page cache and is not counted when
 *  there are more). readAll calls back with each scan's ms and point count. */
template <typename ReadAll>
Result measure(const std::string& label, double megabytes, int passes, ReadAll readAll)
{
	Result r;
	r.label = label;
	r.megabytes = megabytes;
	std::vector<double> ms;
	double points = 0;
	for (int p = 0; p < passes; p++)
	{
		const bool counted = passes == 1 || p > 0;
		readAll(
		    [&](double t, std::size_t n)
		    {
			    if (!counted)
				    return;
			    ms.push_back(t);
			    points += static_cast<double>(n);
		    });
	}
	r.scans = ms.size() / static_cast<std::size_t>(passes == 1 ? 1 : passes - 1);
	r.points = ms.empty() ? 0 : points / static_cast<double>(ms.size());
	r.median = quantile(ms, 0.5);
	r.p95 = quantile(ms, 0.95);
	return r;
}

double megabytesOf(const fs::path& p)
{
	std::uintmax_t n = 0;
	std::error_code ec;
	if (fs::is_directory(p, ec))
	{
		for (const auto& e : fs::directory_iterator(p, ec))
			if (e.is_regular_file(ec) && e.path().extension() == ".bin")
				n += e.file_size(ec);
	}
	else
		n = fs::file_size(p, ec);
	return static_cast<double>(n) / (1024.0 * 1024.0);
}
}  // namespace

int main(int argc, char** argv)
{
	std::string binDir;
	std::vector<std::string> rawlogs;
	int passes = 3;
	CLI::App app(
	    "rasterslam-bench-read: ms per scan to read scans into points, from KITTI .bin files and "
	    "from MRPT rawlogs (plain or gzip), in one process, each scan converted to the "
	    "project's point type as in a run. Passes after the first are counted (the first fills "
	    "the page cache). The ratio column is against the first input.",
	    "rasterslam-bench-read");
	cli::configure(app);
	app.add_option("--bin", binDir, "a folder of KITTI .bin scans")
	    ->check(CLI::ExistingDirectory.description(""))
	    ->type_name("DIR");
	app.add_option("--rawlog", rawlogs, "an MRPT rawlog (repeatable)")
	    ->check(CLI::ExistingFile.description(""))
	    ->type_name("FILE");
	app.add_option("--passes", passes, "passes over each input (default 3)")
	    ->check(CLI::Range(1, 100).description(""))
	    ->type_name("N");
	if (const int rc = cli::parse(app, argc, argv); rc >= 0)
		return rc;
	if (binDir.empty() && rawlogs.empty())
	{
		std::fprintf(stderr,
		             "rasterslam-bench-read: nothing to read: give --bin and/or --rawlog\n");
		return 2;
	}
	std::vector<Result> results;
	try
	{
		if (!binDir.empty())
		{
			const auto files = io::listKittiBins(binDir);
			results.push_back(measure("bin " + binDir, megabytesOf(binDir), passes,
			                          [&](auto&& onScan)
			                          {
				                          for (const auto& f : files)
				                          {
					                          const auto t0 = Clock::now();
					                          const auto pts = io::loadKittiBin(f);
					                          onScan(msSince(t0), pts.size());
				                          }
			                          }));
		}
		for (const auto& path : rawlogs)
			results.push_back(measure("rawlog " + path, megabytesOf(path), passes,
			                          [&](auto&& onScan)
			                          {
				                          io::RawlogSource src(path);
				                          for (;;)
				                          {
					                          const auto t0 = Clock::now();
					                          auto scan = src.next();
					                          const double t = msSince(t0);
					                          if (!scan)
						                          break;
					                          onScan(t, scan->points.size());
				                          }
				                          if (!src.stopReason().empty())
					                          throw std::runtime_error(src.stopReason());
			                          }));
	}
	catch (const std::exception& e)
	{
		std::fprintf(stderr, "rasterslam-bench-read: %s\n", e.what());
		return 1;
	}
	std::printf("%-8s %8s %6s %8s %9s %9s %7s  %s\n", "format", "MB", "scans", "points", "ms/scan",
	            "p95 ms", "ratio", "input");
	for (const auto& r : results)
	{
		const auto space = r.label.find(' ');
		std::printf("%-8s %8.0f %6zu %8.0f %9.3f %9.3f %7.2f  %s\n",
		            r.label.substr(0, space).c_str(), r.megabytes, r.scans, r.points, r.median,
		            r.p95, results.front().median > 0 ? r.median / results.front().median : 0.0,
		            r.label.substr(space + 1).c_str());
	}
	return 0;
}
