// rasterslam-eval reloc: relocalization accuracy against ground truth.
#include <fstream>
#include <map>

#include "cli.h"

namespace rasterslam_eval_cli
{
namespace
{
const char* kRelocAbout =
    "Accuracy of `rasterslam relocalize`: R (--reloc) is its relocalization.txt; Q (--gt) the "
    "queries' ground truth (TUM, same stamps); the map run's groundtruth.tum (--map-gt) and "
    "trajectory.tum (--map-est) give the matched keyframe's true and estimated pose. The error "
    "of a found query is that of its pose relative to the matched keyframe (so the map's own "
    "drift does not count). A found query is correct within --max-trans and --max-rot, wrong "
    "beyond --wrong-trans or --wrong-rot, inaccurate in between. Queries are grouped by the "
    "way they face against the nearest map pose (same: within 90 degrees) and by their "
    "distance to it.";

struct RelocOptions
{
	std::string reloc, gt, mapGt, mapEst;
	double maxTrans = 0.3, maxRotDeg = 1.0, wrongTrans = 2.0, wrongRotDeg = 10.0;
	bool json = false;
};

struct Line
{
	double stamp = 0, kfStamp = 0, score = 0;
	bool found = false;
	std::size_t inliers = 0;
	Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
};

std::vector<Line> readReloc(const std::string& path)
{
	std::ifstream f(path);
	if (!f)
		throw std::runtime_error(path + ": cannot be read");
	std::vector<Line> out;
	std::string text;
	std::size_t n = 0;
	while (std::getline(f, text))
	{
		n++;
		if (text.empty() || text[0] == '#')
			continue;
		std::istringstream ss(text);
		Line l;
		std::string status, reason;
		unsigned long long lm = 0, kf = 0;
		double x, y, z, qx, qy, qz, qw;
		ss >> l.stamp >> status >> reason >> lm >> kf >> l.kfStamp >> l.score >> l.inliers >> x >>
		    y >> z >> qx >> qy >> qz >> qw;
		if (ss.fail() || (status != "found" && status != "not_found"))
			throw std::runtime_error(path + ":" + std::to_string(n) +
			                         ": not a relocalization line (stamp status reason local_map "
			                         "keyframe keyframe_stamp score inliers x y z qx qy qz qw)");
		l.found = status == "found";
		const Eigen::Quaterniond q(qw, qx, qy, qz);
		if (l.found && std::abs(q.norm() - 1) > 1e-3)
			throw std::runtime_error(path + ":" + std::to_string(n) + ": quaternion not unit");
		l.pose.linear() = q.normalized().toRotationMatrix();
		l.pose.translation() = Eigen::Vector3d(x, y, z);
		out.push_back(l);
	}
	return out;
}

const Eigen::Isometry3d* poseAt(const io::Trajectory& t, double stamp)
{
	for (const auto& p : t)
		if (std::abs(p.stamp - stamp) < 1e-4)
			return &p.pose;
	return nullptr;
}

double angleDeg(const Eigen::Matrix3d& R)
{
	return Eigen::AngleAxisd(R).angle() * 180 / M_PI;
}

struct Group
{
	std::size_t queries = 0, found = 0, correct = 0, inaccurate = 0, wrong = 0;
	std::vector<double> trans, rot, height, tilt;
};

int runReloc(const RelocOptions& o)
{
	const auto lines = readReloc(o.reloc);
	const auto gt = io::loadTrajectory(o.gt), mapGt = io::loadTrajectory(o.mapGt),
	           mapEst = io::loadTrajectory(o.mapEst);
	if (mapGt.empty())
		throw std::runtime_error(o.mapGt + ": no pose");
	std::map<std::string, Group> groups;
	Group all;
	for (const auto& l : lines)
	{
		const auto* q = poseAt(gt, l.stamp);
		if (!q)
			throw std::runtime_error(o.gt + ": no pose at the query stamp " + numberText(l.stamp) +
			                         " of " + o.reloc);
		// The nearest map pose: distance and the way the query faces against it.
		double best = 1e300;
		double headingDeg = 0;
		for (const auto& m : mapGt)
		{
			const double d = (m.pose.translation() - q->translation()).norm();
			if (d < best)
			{
				best = d;
				const Eigen::Vector3d a = m.pose.linear().col(0), b = q->linear().col(0);
				headingDeg = std::acos(std::clamp(a.dot(b), -1.0, 1.0)) * 180 / M_PI;
			}
		}
		const std::string dir = headingDeg < 90 ? "same" : "opposite";
		const std::string dist =
		    best < 1
		        ? "0-1m"
		        : (best < 4 ? "1-4m"
		                    : (best < 7 ? "4-7m"
		                                : (best < 15 ? "7-15m" : (best < 30 ? "15-30m" : ">30m"))));
		auto& g = groups[dir + " " + dist];
		for (Group* x : {&g, &all})
		{
			x->queries++;
			if (!l.found)
				continue;
			x->found++;
			const auto *kg = poseAt(mapGt, l.kfStamp), *ke = poseAt(mapEst, l.kfStamp);
			if (!kg || !ke)
				throw std::runtime_error("no pose at the keyframe stamp " + numberText(l.kfStamp) +
				                         " in " + o.mapGt + " or " + o.mapEst);
			const Eigen::Isometry3d E = (kg->inverse() * *q).inverse() * (ke->inverse() * l.pose);
			const double t = E.translation().norm(), r = angleDeg(E.linear());
			x->trans.push_back(t);
			x->rot.push_back(r);
			// Height and tilt, in the matched keyframe's frame: what a ground plane fixes.
			const Eigen::Isometry3d Tt = kg->inverse() * *q, Te = ke->inverse() * l.pose;
			x->height.push_back(std::abs(Te.translation().z() - Tt.translation().z()));
			x->tilt.push_back(
			    std::acos(std::clamp(Te.linear().col(2).dot(Tt.linear().col(2)), -1.0, 1.0)) * 180 /
			    M_PI);
			if (t <= o.maxTrans && r <= o.maxRotDeg)
				x->correct++;
			else if (t >= o.wrongTrans || r >= o.wrongRotDeg)
				x->wrong++;
			else
				x->inaccurate++;
		}
	}
	const auto median = [](std::vector<double> v)
	{
		if (v.empty())
			return std::nan("");
		std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
		return v[v.size() / 2];
	};
	const auto rate = [](std::size_t a, std::size_t b)
	{ return b ? static_cast<double>(a) / static_cast<double>(b) : std::nan(""); };
	const auto toJson = [&](const Group& g)
	{
		Json j;
		j["queries"] = g.queries;
		j["found"] = g.found;
		j["correct"] = g.correct;
		j["inaccurate"] = g.inaccurate;
		j["wrong"] = g.wrong;
		j["correct_rate"] = jsonNumber(rate(g.correct, g.queries));
		j["median_trans_m"] = jsonNumber(median(g.trans));
		j["median_rot_deg"] = jsonNumber(median(g.rot));
		j["median_height_m"] = jsonNumber(median(g.height));
		j["median_tilt_deg"] = jsonNumber(median(g.tilt));
		return j;
	};
	if (o.json)
	{
		Json j = toJson(all);
		Json gs = Json::object();
		for (const auto& [k, g] : groups)
			gs[k] = toJson(g);
		j["groups"] = gs;
		std::cout << jsonLine(j);
		return 0;
	}
	std::printf("correct: within %.2f m and %.2f deg of the truth; wrong: %.1f m or %.1f deg off\n",
	            o.maxTrans, o.maxRotDeg, o.wrongTrans, o.wrongRotDeg);
	std::printf("%-16s %7s %6s %8s %11s %6s %9s %9s %9s %9s\n", "group", "queries", "found",
	            "correct", "inaccurate", "wrong", "median m", "deg", "height m", "tilt deg");
	const auto row = [&](const std::string& name, const Group& g)
	{
		std::printf("%-16s %7zu %6zu %8zu %11zu %6zu %9.3f %9.3f %9.3f %9.3f\n", name.c_str(),
		            g.queries, g.found, g.correct, g.inaccurate, g.wrong, median(g.trans),
		            median(g.rot), median(g.height), median(g.tilt));
	};
	for (const auto& [k, g] : groups)
		row(k, g);
	row("all", all);
	return 0;
}

}  // namespace

Command addReloc(CLI::App& app)
{
	CLI::App* sub =
	    cli::subcommand(app, "reloc", "relocalization accuracy against ground truth", kRelocAbout);
	auto o = std::make_shared<RelocOptions>();
	sub->add_option("--reloc", o->reloc, "relocalization.txt R of rasterslam relocalize")
	    ->required()
	    ->check(cli::unnamed(CLI::ExistingFile))
	    ->type_name("FILE");
	sub->add_option("--gt", o->gt, "ground truth of the queries Q (TUM)")
	    ->required()
	    ->check(cli::unnamed(CLI::ExistingFile))
	    ->type_name("FILE");
	sub->add_option("--map-gt", o->mapGt, "the map run's groundtruth.tum")
	    ->required()
	    ->check(cli::unnamed(CLI::ExistingFile))
	    ->type_name("FILE");
	sub->add_option("--map-est", o->mapEst, "the map run's trajectory.tum")
	    ->required()
	    ->check(cli::unnamed(CLI::ExistingFile))
	    ->type_name("FILE");
	sub->add_option("--max-trans", o->maxTrans, "largest error of a correct pose (m)")
	    ->check(nonNegativeNumber())
	    ->type_name("M")
	    ->capture_default_str();
	sub->add_option("--max-rot", o->maxRotDeg, "largest error of a correct pose (deg)")
	    ->check(nonNegativeNumber())
	    ->type_name("DEG")
	    ->capture_default_str();
	sub->add_option("--wrong-trans", o->wrongTrans, "smallest error of a wrong pose (m)")
	    ->check(nonNegativeNumber())
	    ->type_name("M")
	    ->capture_default_str();
	sub->add_option("--wrong-rot", o->wrongRotDeg, "smallest error of a wrong pose (deg)")
	    ->check(nonNegativeNumber())
	    ->type_name("DEG")
	    ->capture_default_str();
	sub->add_flag("--json", o->json, "print one JSON object instead of text");
	return {sub, [o] { return runReloc(*o); }};
}

}  // namespace rasterslam_eval_cli
