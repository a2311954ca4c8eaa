// rasterslam-bench-map-store: seconds and bytes to save and load a map of many local maps
// (the lifelong-maps issue: "save and load of a 1,000-local-map store"). The map is
// synthetic but sized like the simulated HDL-64E town's (points a local map, a PNG image),
// drawn from a seeded generator; nothing is kept after the run.
#include <rasterslam/cli/app.h>
#include <rasterslam/map/map.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>

namespace fs = std::filesystem;
using namespace rasterslam;

namespace
{
double seconds(std::chrono::steady_clock::time_point t0)
{
	return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}
double rssMb()
{
	std::ifstream f("/proc/self/status");
	std::string line;
	while (std::getline(f, line))
		if (line.rfind("VmRSS:", 0) == 0)
			return std::stod(line.substr(6)) / 1024.0;
	return -1;
}
std::uintmax_t bytesIn(const fs::path& dir)
{
	std::uintmax_t n = 0;
	std::error_code ec;
	for (const auto& e : fs::recursive_directory_iterator(dir, ec))
		if (e.is_regular_file(ec))
			n += e.file_size(ec);
	return n;
}
}  // namespace

int main(int argc, char** argv)
{
	std::size_t maps = 1000, points = 8000;
	CLI::App app(
	    "rasterslam-bench-map-store: seconds and bytes to save and load a map of many local maps. "
	    "The map is synthetic but sized like the simulated HDL-64E town's (points a local map, a "
	    "PNG image), drawn from a seeded generator, in a folder of the system's temporary "
	    "directory; nothing is kept after the run.",
	    "rasterslam-bench-map-store");
	cli::configure(app);
	const CLI::Validator atLeastOne(
	    [](std::string& v) -> std::string
	    {
		    const bool ok = !v.empty() && v.size() < 19 &&
		                    v.find_first_not_of("0123456789") == std::string::npos &&
		                    v.find_first_not_of('0') != std::string::npos;
		    return ok ? std::string() : "expects a whole number >= 1, got '" + v + "'";
	    },
	    "");
	app.add_option("--local-maps", maps, "local maps in the map (default 1000)")
	    ->check(atLeastOne)
	    ->type_name("N");
	app.add_option("--points", points, "points a local map (default 8000)")
	    ->check(atLeastOne)
	    ->type_name("P");
	if (const int rc = cli::parse(app, argc, argv); rc >= 0)
		return rc;
	const fs::path dir =
	    fs::temp_directory_path() / ("rasterslam-bench-map-store-" + std::to_string(::getpid()));
	std::mt19937 rng(3);
	std::uniform_real_distribution<float> u(-40, 40);

	Map m;
	m.sessions = 1;
	for (std::size_t i = 0; i < maps; i++)
	{
		// Five keyframes a local map, the last shared with the next one.
		auto lm = std::make_shared<LocalMap>();
		lm->id = i;
		for (uint64_t k = 4 * i; k <= 4 * i + 4; k++)
		{
			lm->keyframes.push_back(k);
			if (m.keyframes.count(k))
				continue;
			auto kf = std::make_shared<Keyframe>();
			kf->id = k;
			kf->stamp = static_cast<double>(k);
			m.keyframes[k] = kf;
			m.priorPoses[k] = mrpt::poses::CPose3D(static_cast<double>(k), 0, 0, 0, 0, 0);
		}
		lm->createdStamp = static_cast<double>(4 * i);
		lm->updatedStamp = lm->createdStamp + 4;
		lm->online = false;
		for (std::size_t p = 0; p < points; p++)
		{
			lm->xyz.insert(lm->xyz.end(), {u(rng), u(rng), u(rng) / 8});
			for (int b = 0; b < 32; b++)
				lm->descriptors.push_back(static_cast<uint8_t>(rng()));
			lm->observers.push_back(1u << (rng() % 5));
		}
		lm->imagePng.resize(25000);  // a 600 x 600 image compresses to about this
		for (auto& b : lm->imagePng)
			b = static_cast<uint8_t>(rng());
		m.localMaps[i] = lm;
		if (i)
			m.graph.add(i - 1, i, LocalMapGraph::EdgeKind::Sequential, lm->createdStamp);
	}
	PoseView poses;
	poses.prior = &m.priorPoses;

	int rc = 0;
	try
	{
		auto t0 = std::chrono::steady_clock::now();
		saveMap(m, poses, dir.string());
		const double save1 = seconds(t0);
		const auto disk = bytesIn(dir), index = fs::file_size(mapFilePath(dir.string()));
		const double rss0 = rssMb();
		t0 = std::chrono::steady_clock::now();
		Map back = loadMap(dir.string());
		const double load = seconds(t0);
		const double rssLoaded = rssMb() - rss0;
		PoseView backPoses;
		backPoses.prior = &back.priorPoses;
		t0 = std::chrono::steady_clock::now();
		saveMap(back, backPoses, dir.string());
		const double save2 = seconds(t0);
		t0 = std::chrono::steady_clock::now();
		std::size_t read = 0;
		for (const auto& [id, lm] : back.localMaps)
			read += back.data(id)->points();
		const double readAll = seconds(t0);
		std::printf(
		    "local maps            : %zu of %zu points (%zu keyframes)\n"
		    "on disk               : %.1f MB (index map.rsmap %.2f MB)\n"
		    "save, new folder      : %.2f s\n"
		    "load (index)          : %.3f s, %.1f MB more resident memory\n"
		    "save over itself      : %.3f s (index only: no local map written again)\n"
		    "read every local map  : %.2f s (%.2f ms each, checksum verified)\n",
		    maps, points, m.keyframes.size(), disk / 1e6, index / 1e6, save1, load, rssLoaded,
		    save2, readAll, 1e3 * readAll / static_cast<double>(maps));
		if (read != maps * points)
			rc = 1;
	}
	catch (const std::exception& e)
	{
		std::fprintf(stderr, "rasterslam-bench-map-store: error: %s\n", e.what());
		rc = 1;
	}
	std::error_code ec;
	fs::remove_all(dir, ec);
	return rc;
}
