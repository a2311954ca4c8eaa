// rasterslam-eval traj: ATE, RPE and the KITTI devkit relative errors.
#include <mrpt/core/format.h>

#include <optional>

#include "cli.h"

namespace rasterslam_eval_cli
{
namespace
{
const char* kTrajUsage =
    R"(Usage: rasterslam-eval traj --gt G --est E [options]

Trajectory accuracy of an estimate E against a ground truth G:
  ATE   absolute trajectory error after the best SE(3) alignment (Umeyama, no scale)
  RPE   relative pose error between consecutive poses (per frame)
  KITTI the odometry devkit's relative translation (%) and rotation (deg/m) errors
Files are TUM ("t x y z qx qy qz qw") or KITTI (12 numbers of a 3x4 [R|t]), detected by
their column count. TUM vs TUM are associated by nearest time stamp; otherwise by index.

Options:
  --gt FILE             ground-truth trajectory (required)
  --est FILE            estimated trajectory (required)
  --calib FILE          KITTI calib.txt: G holds cam0 poses; convert them to the Velodyne
                        frame with inv(Tr) * P * Tr (rasterslam outputs Velodyne poses)
  --est-calib FILE      same conversion for E (when E is a KITTI cam0 pose file too)
  --gt-format F         auto|tum|kitti (default auto); --est-format F likewise
  --times FILE          KITTI times.txt: stamps for the KITTI-format file(s)
  --associate M         auto|index|stamp (default auto)
  --align A             se3: fit the estimate to the ground truth (default); or a given
                        T_gt_est as x,y,z,qx,qy,qz,qw (what --json prints as T_gt_est), e.g.
                        another session's alignment, to judge sessions of one map in one frame
  --max-dt S            largest stamp difference when associating by time (default 0.02)
  --segments SPEC       segment lengths in metres, start:end:step or a list
                        (default 100:800:100; use 10:80:10 for short clips)
  --step N              first frames every N associated poses (default 10, as the devkit)
  --json                print one JSON object instead of text
  -h, --help            this help
Exit codes: 0 success, 1 bad input file, 2 bad command line.
)";

io::TrajectoryFormat parseFormat(const std::string& opt, const std::string& s)
{
	if (s == "auto")
		return io::TrajectoryFormat::Auto;
	if (s == "tum")
		return io::TrajectoryFormat::Tum;
	if (s == "kitti")
		return io::TrajectoryFormat::Kitti;
	throw UsageError("option " + opt + ": expected auto, tum or kitti, got '" + s + "'");
}

struct Input
{
	io::Trajectory traj;
	io::TrajectoryFormat format = io::TrajectoryFormat::Auto;
	bool stamped = false;  //!< real time stamps (TUM, or KITTI with --times)
};

Input loadInput(const Options& o, const std::string& fileOpt, const std::string& fmtOpt,
                const std::string& calibOpt)
{
	Input in;
	const std::string path = o.require(fileOpt);
	in.traj = io::loadTrajectory(path, parseFormat(fmtOpt, o.get(fmtOpt, "auto")), &in.format);
	if (in.traj.empty())
		throw std::runtime_error("trajectory file '" + path + "' has no poses");
	in.stamped = in.format == io::TrajectoryFormat::Tum;
	if (in.format == io::TrajectoryFormat::Kitti && o.has("--times"))
	{
		const auto times = io::loadKittiTimes(o.get("--times"));
		if (times.size() != in.traj.size())
		{
			throw std::runtime_error("times file '" + o.get("--times") + "' has " +
			                         std::to_string(times.size()) + " stamps but '" + path +
			                         "' has " + std::to_string(in.traj.size()) + " poses");
		}
		for (std::size_t i = 0; i < times.size(); ++i)
			in.traj[i].stamp = times[i];
		in.stamped = true;
	}
	if (o.has(calibOpt))
		in.traj = io::kittiCameraToVelodyne(in.traj, io::loadKittiCalibTr(o.get(calibOpt)));
	return in;
}
}  // namespace

int runTraj(int argc, char** argv)
{
	const Options o(argc, argv,
	                {"--gt", "--est", "--calib", "--est-calib", "--gt-format", "--est-format",
	                 "--times", "--associate", "--max-dt", "--segments", "--step", "--align"},
	                {"--json", "--help", "-h"});
	if (o.flag("--help") || o.flag("-h"))
	{
		std::cout << kTrajUsage;
		return 0;
	}
	// Check the whole command line before reading any file.
	o.require("--gt");
	o.require("--est");
	parseFormat("--gt-format", o.get("--gt-format", "auto"));
	parseFormat("--est-format", o.get("--est-format", "auto"));
	const std::string segSpec = o.get("--segments", "100:800:100");
	std::vector<double> lengths;
	try
	{
		lengths = eval::parseSegmentSpec(segSpec);
	}
	catch (const std::invalid_argument& e)
	{
		throw UsageError(std::string("option --segments: ") + e.what());
	}
	const double maxDt = o.number("--max-dt", 0.02);
	const double stepD = o.number("--step", 10);
	if (stepD < 1 || stepD != std::floor(stepD))
		throw UsageError("option --step: expected a whole number >= 1");
	const auto step = static_cast<std::size_t>(stepD);
	const std::string assocMode = o.get("--associate", "auto");
	if (assocMode != "auto" && assocMode != "index" && assocMode != "stamp")
		throw UsageError("option --associate: expected auto, index or stamp, got '" + assocMode +
		                 "'");

	// --align se3 (fit) or x,y,z,qx,qy,qz,qw: a given T_gt_est (as --json prints it).
	std::optional<Eigen::Isometry3d> fixedAlign;
	if (const std::string al = o.get("--align", "se3"); al != "se3")
	{
		std::vector<double> v;
		std::stringstream ss(al);
		std::string item;
		while (std::getline(ss, item, ','))
		{
			char* end = nullptr;
			const double x = std::strtod(item.c_str(), &end);
			if (item.empty() || *end || !std::isfinite(x))
				throw UsageError("option --align: expected se3 or x,y,z,qx,qy,qz,qw, got '" + al +
				                 "'");
			v.push_back(x);
		}
		const Eigen::Quaterniond q(v.size() == 7 ? v[6] : 0, v.size() == 7 ? v[3] : 0,
		                           v.size() == 7 ? v[4] : 0, v.size() == 7 ? v[5] : 0);
		if (v.size() != 7 || std::abs(q.norm() - 1) > 1e-3)
			throw UsageError(
			    "option --align: expected se3 or x,y,z,qx,qy,qz,qw with a unit quaternion, got '" +
			    al + "'");
		fixedAlign = Eigen::Isometry3d::Identity();
		fixedAlign->linear() = q.normalized().toRotationMatrix();
		fixedAlign->translation() = Eigen::Vector3d(v[0], v[1], v[2]);
	}

	const Input gt = loadInput(o, "--gt", "--gt-format", "--calib");
	const Input est = loadInput(o, "--est", "--est-format", "--est-calib");

	const bool byStamp = assocMode == "stamp" || (assocMode == "auto" && gt.stamped && est.stamped);
	const eval::Association a = eval::associate(gt.traj, est.traj, !byStamp, maxDt);
	if (a.gt.size() < 2)
	{
		throw std::runtime_error("only " + std::to_string(a.gt.size()) +
		                         " pose pairs associated between '" + o.get("--gt") + "' and '" +
		                         o.get("--est") + "'" +
		                         (byStamp ? " (check the stamps or --max-dt)" : ""));
	}

	const eval::AteResult ate = eval::computeAte(gt.traj, est.traj, a, fixedAlign);
	const Eigen::Quaterniond alignQ(ate.T_gt_est.linear());
	const Eigen::Vector3d alignT = ate.T_gt_est.translation();
	const eval::RpeResult rpe = eval::computeRpe(gt.traj, est.traj, a);
	const eval::KittiRelativeResult rel =
	    eval::computeKittiRelative(gt.traj, est.traj, a, lengths, step);
	const double pathLength = eval::trajectoryDistances(gt.traj, a).back();
	const bool relOk = rel.count > 0;
	double shortest = lengths.front();
	for (double l : lengths)
		shortest = std::min(shortest, l);
	std::ostringstream note;
	if (!relOk)
	{
		note << std::fixed << std::setprecision(2) << "path length " << pathLength
		     << " m is shorter than the shortest segment " << shortest
		     << " m; try --segments 10:80:10";
	}

	if (o.flag("--json"))
	{
		std::ostringstream j;
		j << "{\"gt\": " << jsonString(o.get("--gt")) << ", \"est\": " << jsonString(o.get("--est"))
		  << ", \"n_gt\": " << gt.traj.size() << ", \"n_est\": " << est.traj.size()
		  << ", \"n_associated\": " << a.gt.size() << ", \"association\": \""
		  << (byStamp ? "stamp" : "index") << "\", \"path_length_m\": " << jsonNumber(pathLength)
		  << ", \"ate_rmse_m\": " << jsonNumber(ate.rmse_m)
		  << ", \"ate_mean_m\": " << jsonNumber(ate.mean_m)
		  << ", \"ate_median_m\": " << jsonNumber(ate.median_m)
		  << ", \"ate_max_m\": " << jsonNumber(ate.max_m) << ", \"ate_alignment\": \""
		  << (fixedAlign ? "given" : "se3") << "\", \"T_gt_est\": \""
		  << mrpt::format("%.9g,%.9g,%.9g,%.9g,%.9g,%.9g,%.9g", alignT.x(), alignT.y(), alignT.z(),
		                  alignQ.x(), alignQ.y(), alignQ.z(), alignQ.w())
		  << "\", \"rpe_pairs\": " << rpe.n
		  << ", \"rpe_trans_rmse_m\": " << jsonNumber(rpe.trans_rmse_m)
		  << ", \"rpe_trans_mean_m\": " << jsonNumber(rpe.trans_mean_m)
		  << ", \"rpe_rot_rmse_deg\": " << jsonNumber(rpe.rot_rmse_deg)
		  << ", \"rpe_rot_mean_deg\": " << jsonNumber(rpe.rot_mean_deg) << ", \"segments\": [";
		for (std::size_t i = 0; i < lengths.size(); ++i)
			j << (i ? ", " : "") << jsonNumber(lengths[i]);
		j << "], \"step\": " << step << ", \"rel_count\": " << rel.count
		  << ", \"rel_trans_pct\": " << jsonNumber(rel.t_err_pct, relOk)
		  << ", \"rel_rot_deg_per_m\": " << jsonNumber(rel.r_err_deg_per_m, relOk)
		  << ", \"per_length\": [";
		for (std::size_t i = 0; i < rel.perLength.size(); ++i)
		{
			const auto& pl = rel.perLength[i];
			j << (i ? ", " : "") << "{\"length_m\": " << jsonNumber(pl.length_m)
			  << ", \"count\": " << pl.count
			  << ", \"t_err_pct\": " << jsonNumber(pl.t_err_pct, pl.count > 0)
			  << ", \"r_err_deg_per_m\": " << jsonNumber(pl.r_err_deg_per_m, pl.count > 0) << "}";
		}
		j << "], \"note\": " << (relOk ? "null" : jsonString(note.str())) << "}\n";
		std::cout << j.str();
		return 0;
	}

	auto fmtName = [](io::TrajectoryFormat f)
	{ return f == io::TrajectoryFormat::Tum ? "TUM" : "KITTI"; };
	char buf[256];
	std::cout << "ground truth : " << o.get("--gt") << " (" << fmtName(gt.format) << ", "
	          << gt.traj.size() << " poses" << (o.has("--calib") ? ", cam0 -> Velodyne" : "")
	          << ")\n"
	          << "estimate     : " << o.get("--est") << " (" << fmtName(est.format) << ", "
	          << est.traj.size() << " poses" << (o.has("--est-calib") ? ", cam0 -> Velodyne" : "")
	          << ")\n"
	          << "associated   : " << a.gt.size() << " pairs by "
	          << (byStamp ? "time stamp" : "index") << "\n";
	std::snprintf(buf, sizeof(buf), "path length  : %.2f m (ground truth)\n", pathLength);
	std::cout << buf;
	std::snprintf(buf, sizeof(buf),
	              "ATE (%s): rmse %.4f m, mean %.4f m, median %.4f m, max %.4f m\n",
	              fixedAlign ? "given alignment" : "SE(3)-aligned", ate.rmse_m, ate.mean_m,
	              ate.median_m, ate.max_m);
	std::cout << buf;
	std::snprintf(
	    buf, sizeof(buf),
	    "RPE per frame (%zu pairs): translation rmse %.4f m, mean %.4f m; rotation rmse %.4f deg, "
	    "mean %.4f deg\n",
	    rpe.n, rpe.trans_rmse_m, rpe.trans_mean_m, rpe.rot_rmse_deg, rpe.rot_mean_deg);
	std::cout << buf;
	if (!relOk)
	{
		std::cout << "KITTI relative errors: no segment (" << note.str() << ")\n";
		return 0;
	}
	std::snprintf(buf, sizeof(buf),
	              "KITTI relative errors (segments %s m, every %zu frames, %zu segments): "
	              "translation %.3f %%, rotation %.5f deg/m\n",
	              segSpec.c_str(), step, rel.count, rel.t_err_pct, rel.r_err_deg_per_m);
	std::cout << buf << "  length_m  count  t_err_%   r_err_deg/m\n";
	for (const auto& pl : rel.perLength)
	{
		if (pl.count)
			std::snprintf(buf, sizeof(buf), "  %8.1f  %5zu  %7.3f   %.5f\n", pl.length_m, pl.count,
			              pl.t_err_pct, pl.r_err_deg_per_m);
		else
			std::snprintf(buf, sizeof(buf), "  %8.1f  %5zu        -   -\n", pl.length_m, pl.count);
		std::cout << buf;
	}
	return 0;
}

}  // namespace rasterslam_eval_cli
