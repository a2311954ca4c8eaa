// rasterslam-eval traj: ATE, RPE and the KITTI devkit relative errors.
#include <mrpt/core/format.h>
#include <rasterslam/eval/trajectory_plot.h>

#include <filesystem>
#include <optional>

#include "cli.h"

namespace rasterslam_eval_cli
{
namespace
{
// Below the options in --help (the formatter wraps it at 100 columns, keeping line breaks).
const char* kTrajAbout =
    "Trajectory accuracy of an estimate E (--est) against a ground truth G (--gt):\n"
    "ATE: absolute trajectory error after the best SE(3) alignment (Umeyama, no scale);\n"
    "RPE: relative pose error between consecutive poses (per frame);\n"
    "KITTI: the odometry devkit's relative translation (%) and rotation (deg/m) errors.\n"
    "Files are TUM (\"t x y z qx qy qz qw\") or KITTI (12 numbers of a 3x4 [R|t]), detected by "
    "their column count. TUM vs TUM are associated by nearest time stamp; otherwise by index.";

struct TrajOptions
{
	std::string gt, est, calib, estCalib, times;
	std::string gtFormat = "auto", estFormat = "auto", associate = "auto", align = "se3";
	std::string segments = "100:800:100";
	double maxDt = 0.02;
	std::size_t step = 10;
	bool json = false;
	std::string plot;                   //!< PNG of the trajectories from above
	std::vector<std::string> plotAlso;  //!< more estimates drawn on it
	std::vector<std::string> labels;    //!< legend names: E, then each --plot-also
	std::string title;                  //!< of the plot
};

/** A legend name from a trajectory's path: its folder ("runs/kiss/trajectory.kitti" ->
 *  "kiss"), or the file name without extension. */
std::string nameOf(const std::string& path)
{
	const std::filesystem::path p(path);
	const std::string folder = p.parent_path().filename().string();
	return folder.empty() || folder == "." ? p.stem().string() : folder;
}

io::TrajectoryFormat parseFormat(const std::string& s)
{
	if (s == "tum")
		return io::TrajectoryFormat::Tum;
	if (s == "kitti")
		return io::TrajectoryFormat::Kitti;
	return io::TrajectoryFormat::Auto;  // "auto": CLI11 lets no other value through
}

/** --align: "se3" (fit: no value) or a given T_gt_est as x,y,z,qx,qy,qz,qw (as --json prints
 *  it). Throws std::invalid_argument with what is wrong. */
std::optional<Eigen::Isometry3d> parseAlign(const std::string& al)
{
	if (al == "se3")
		return std::nullopt;
	std::vector<double> v;
	std::stringstream ss(al);
	std::string item;
	while (std::getline(ss, item, ','))
	{
		char* end = nullptr;
		const double x = std::strtod(item.c_str(), &end);
		if (item.empty() || *end || !std::isfinite(x))
			throw std::invalid_argument("expected se3 or x,y,z,qx,qy,qz,qw, got '" + al + "'");
		v.push_back(x);
	}
	const Eigen::Quaterniond q(v.size() == 7 ? v[6] : 0, v.size() == 7 ? v[3] : 0,
	                           v.size() == 7 ? v[4] : 0, v.size() == 7 ? v[5] : 0);
	if (v.size() != 7 || std::abs(q.norm() - 1) > 1e-3)
		throw std::invalid_argument(
		    "expected se3 or x,y,z,qx,qy,qz,qw with a unit quaternion, got '" + al + "'");
	Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
	T.linear() = q.normalized().toRotationMatrix();
	T.translation() = Eigen::Vector3d(v[0], v[1], v[2]);
	return T;
}

/** A validator from a parser that throws std::invalid_argument. */
template <typename Parse>
CLI::Validator parses(Parse parse)
{
	return CLI::Validator(
	    [parse](std::string& s) -> std::string
	    {
		    try
		    {
			    parse(s);
			    return {};
		    }
		    catch (const std::invalid_argument& e)
		    {
			    return e.what();
		    }
	    },
	    "");
}

struct Input
{
	io::Trajectory traj;
	io::TrajectoryFormat format = io::TrajectoryFormat::Auto;
	bool stamped = false;  //!< real time stamps (TUM, or KITTI with --times)
};

Input loadInput(const TrajOptions& o, const std::string& path, const std::string& format,
                const std::string& calib)
{
	Input in;
	in.traj = io::loadTrajectory(path, parseFormat(format), &in.format);
	if (in.traj.empty())
		throw std::runtime_error("trajectory file '" + path + "' has no poses");
	in.stamped = in.format == io::TrajectoryFormat::Tum;
	if (in.format == io::TrajectoryFormat::Kitti && !o.times.empty())
	{
		const auto times = io::loadKittiTimes(o.times);
		if (times.size() != in.traj.size())
		{
			throw std::runtime_error("times file '" + o.times + "' has " +
			                         std::to_string(times.size()) + " stamps but '" + path +
			                         "' has " + std::to_string(in.traj.size()) + " poses");
		}
		for (std::size_t i = 0; i < times.size(); ++i)
			in.traj[i].stamp = times[i];
		in.stamped = true;
	}
	if (!calib.empty())
		in.traj = io::kittiCameraToVelodyne(in.traj, io::loadKittiCalibTr(calib));
	return in;
}

int runTraj(const TrajOptions& o)
{
	// CLI11 has checked every option: these parse what it let through.
	const std::vector<double> lengths = eval::parseSegmentSpec(o.segments);
	const std::optional<Eigen::Isometry3d> fixedAlign = parseAlign(o.align);
	const std::size_t step = o.step;
	const double maxDt = o.maxDt;
	const std::string& assocMode = o.associate;
	const std::string& segSpec = o.segments;

	const Input gt = loadInput(o, o.gt, o.gtFormat, o.calib);
	const Input est = loadInput(o, o.est, o.estFormat, o.estCalib);

	const bool byStamp = assocMode == "stamp" || (assocMode == "auto" && gt.stamped && est.stamped);
	const eval::Association a = eval::associate(gt.traj, est.traj, !byStamp, maxDt);
	if (a.gt.size() < 2)
	{
		throw std::runtime_error("only " + std::to_string(a.gt.size()) +
		                         " pose pairs associated between '" + o.gt + "' and '" + o.est +
		                         "'" + (byStamp ? " (check the stamps or --max-dt)" : ""));
	}

	const eval::AteResult ate = eval::computeAte(gt.traj, est.traj, a, fixedAlign);
	if (!o.plot.empty())
	{
		// Each estimate aligned on the ground truth as E is (its own SE(3) fit, or the given).
		std::vector<eval::PlottedTrajectory> drawn;
		char ateText[64];
		const auto label = [&](std::size_t k, const std::string& path, double rmse)
		{
			std::snprintf(ateText, sizeof(ateText), " (ATE %.3f m)", rmse);
			return (k < o.labels.size() ? o.labels[k] : nameOf(path)) + ateText;
		};
		drawn.push_back(
		    eval::alignedForPlot(est.traj, a, ate.T_gt_est, label(0, o.est, ate.rmse_m)));
		for (std::size_t k = 0; k < o.plotAlso.size(); k++)
		{
			const Input more = loadInput(o, o.plotAlso[k], o.estFormat, o.estCalib);
			const bool stamps =
			    assocMode == "stamp" || (assocMode == "auto" && gt.stamped && more.stamped);
			const eval::Association am = eval::associate(gt.traj, more.traj, !stamps, maxDt);
			if (am.gt.size() < 2)
				throw std::runtime_error("only " + std::to_string(am.gt.size()) +
				                         " pose pairs associated between '" + o.gt + "' and '" +
				                         o.plotAlso[k] + "'");
			const eval::AteResult am_ate = eval::computeAte(gt.traj, more.traj, am, fixedAlign);
			drawn.push_back(eval::alignedForPlot(more.traj, am, am_ate.T_gt_est,
			                                     label(k + 1, o.plotAlso[k], am_ate.rmse_m)));
		}
		std::vector<Eigen::Vector2d> gtXY;
		for (const std::size_t i : a.gt)
			gtXY.emplace_back(gt.traj[i].pose.translation().x(), gt.traj[i].pose.translation().y());
		eval::writePng(o.plot, eval::renderTrajectoryPlot(
		                           gtXY, drawn, o.title.empty() ? "from above: " + o.gt : o.title));
	}
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

	if (o.json)
	{
		Json j;
		j["gt"] = o.gt;
		j["est"] = o.est;
		j["n_gt"] = gt.traj.size();
		j["n_est"] = est.traj.size();
		j["n_associated"] = a.gt.size();
		j["association"] = byStamp ? "stamp" : "index";
		j["path_length_m"] = jsonNumber(pathLength);
		j["ate_rmse_m"] = jsonNumber(ate.rmse_m);
		j["ate_mean_m"] = jsonNumber(ate.mean_m);
		j["ate_median_m"] = jsonNumber(ate.median_m);
		j["ate_max_m"] = jsonNumber(ate.max_m);
		j["ate_alignment"] = fixedAlign ? "given" : "se3";
		// A string that --align takes back.
		j["T_gt_est"] = mrpt::format("%.9g,%.9g,%.9g,%.9g,%.9g,%.9g,%.9g", alignT.x(), alignT.y(),
		                             alignT.z(), alignQ.x(), alignQ.y(), alignQ.z(), alignQ.w());
		j["rpe_pairs"] = rpe.n;
		j["rpe_trans_rmse_m"] = jsonNumber(rpe.trans_rmse_m);
		j["rpe_trans_mean_m"] = jsonNumber(rpe.trans_mean_m);
		j["rpe_rot_rmse_deg"] = jsonNumber(rpe.rot_rmse_deg);
		j["rpe_rot_mean_deg"] = jsonNumber(rpe.rot_mean_deg);
		j["rot_drift_deg_per_100m"] = {jsonNumber(rpe.rot_drift_deg_per_100m.x()),
		                               jsonNumber(rpe.rot_drift_deg_per_100m.y()),
		                               jsonNumber(rpe.rot_drift_deg_per_100m.z())};
		j["segments"] = Json::array();
		for (const double l : lengths)
			j["segments"].push_back(jsonNumber(l));
		j["step"] = step;
		j["rel_count"] = rel.count;
		j["rel_trans_pct"] = jsonNumber(rel.t_err_pct, relOk);
		j["rel_rot_deg_per_m"] = jsonNumber(rel.r_err_deg_per_m, relOk);
		j["per_length"] = Json::array();
		for (const auto& pl : rel.perLength)
		{
			j["per_length"].push_back(
			    {{"length_m", jsonNumber(pl.length_m)},
			     {"count", pl.count},
			     {"t_err_pct", jsonNumber(pl.t_err_pct, pl.count > 0)},
			     {"r_err_deg_per_m", jsonNumber(pl.r_err_deg_per_m, pl.count > 0)}});
		}
		j["note"] = relOk ? Json(nullptr) : Json(note.str());
		std::cout << jsonLine(j);
		return 0;
	}

	auto fmtName = [](io::TrajectoryFormat f)
	{ return f == io::TrajectoryFormat::Tum ? "TUM" : "KITTI"; };
	char buf[256];
	std::cout << "ground truth : " << o.gt << " (" << fmtName(gt.format) << ", " << gt.traj.size()
	          << " poses" << (!o.calib.empty() ? ", cam0 -> Velodyne" : "") << ")\n"
	          << "estimate     : " << o.est << " (" << fmtName(est.format) << ", "
	          << est.traj.size() << " poses" << (!o.estCalib.empty() ? ", cam0 -> Velodyne" : "")
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
	std::snprintf(buf, sizeof(buf),
	              "rotation drift by axis (per-frame errors added up, per 100 m): roll %+.3f, "
	              "pitch %+.3f, yaw %+.3f deg\n",
	              rpe.rot_drift_deg_per_100m.x(), rpe.rot_drift_deg_per_100m.y(),
	              rpe.rot_drift_deg_per_100m.z());
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

}  // namespace

Command addTraj(CLI::App& app)
{
	CLI::App* sub = cli::subcommand(
	    app, "traj", "trajectory errors: ATE, per-frame RPE, KITTI relative errors", kTrajAbout);
	auto o = std::make_shared<TrajOptions>();
	const auto formats = cli::unnamed(CLI::IsMember({"auto", "tum", "kitti"}));
	sub->add_option("--gt", o->gt, "ground-truth trajectory G")
	    ->required()
	    ->check(cli::unnamed(CLI::ExistingFile))
	    ->type_name("FILE");
	sub->add_option("--est", o->est, "estimated trajectory E")
	    ->required()
	    ->check(cli::unnamed(CLI::ExistingFile))
	    ->type_name("FILE");
	sub->add_option("--calib", o->calib,
	                "KITTI calib.txt: G holds cam0 poses; convert them to the Velodyne frame with "
	                "inv(Tr) * P * Tr (rasterslam outputs Velodyne poses)")
	    ->check(cli::unnamed(CLI::ExistingFile))
	    ->type_name("FILE");
	sub->add_option("--est-calib", o->estCalib,
	                "same conversion for E (when E is a KITTI cam0 pose file too)")
	    ->check(cli::unnamed(CLI::ExistingFile))
	    ->type_name("FILE");
	sub->add_option("--gt-format", o->gtFormat, "format of G: auto, tum or kitti")
	    ->check(formats)
	    ->type_name("F")
	    ->capture_default_str();
	sub->add_option("--est-format", o->estFormat, "format of E: auto, tum or kitti")
	    ->check(formats)
	    ->type_name("F")
	    ->capture_default_str();
	sub->add_option("--times", o->times, "KITTI times.txt: stamps for the KITTI-format file(s)")
	    ->check(cli::unnamed(CLI::ExistingFile))
	    ->type_name("FILE");
	sub->add_option("--associate", o->associate,
	                "pose pairs by auto, index or stamp (auto: by time stamp when both files "
	                "have stamps, else by index)")
	    ->check(cli::unnamed(CLI::IsMember({"auto", "index", "stamp"})))
	    ->type_name("M")
	    ->capture_default_str();
	sub->add_option("--align", o->align,
	                "se3: fit the estimate to the ground truth; or a given T_gt_est as "
	                "x,y,z,qx,qy,qz,qw (what --json prints as T_gt_est), e.g. another session's "
	                "alignment, to judge sessions of one map in one frame")
	    ->check(parses(parseAlign))
	    ->type_name("A")
	    ->capture_default_str();
	sub->add_option("--max-dt", o->maxDt, "largest stamp difference when associating by time (s)")
	    ->check(nonNegativeNumber())
	    ->type_name("S")
	    ->capture_default_str();
	sub->add_option("--segments", o->segments,
	                "segment lengths in metres, start:end:step or a list (use 10:80:10 for short "
	                "clips)")
	    ->check(parses(eval::parseSegmentSpec))
	    ->type_name("SPEC")
	    ->capture_default_str();
	sub->add_option("--step", o->step, "first frames every N associated poses (10: as the devkit)")
	    ->check(wholeNumber(1, 1000000000))
	    ->type_name("N")
	    ->capture_default_str();
	sub->add_flag("--json", o->json, "print one JSON object instead of text");
	sub->add_option("--plot", o->plot,
	                "write a PNG of the ground truth and E from above (E aligned as for the ATE)")
	    ->type_name("PNG");
	sub->add_option("--plot-also", o->plotAlso,
	                "another estimate to draw on the --plot (repeatable; each aligned on its own)")
	    ->check(cli::unnamed(CLI::ExistingFile))
	    ->type_name("FILE");
	sub->add_option("--label", o->labels,
	                "legend name of E, then of each --plot-also in order (default: the file's "
	                "folder)")
	    ->type_name("NAME");
	sub->add_option("--title", o->title, "title of the --plot (default: the ground truth's path)")
	    ->type_name("TEXT");
	return {sub, [o] { return runTraj(*o); }};
}

}  // namespace rasterslam_eval_cli
