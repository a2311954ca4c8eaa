// Trajectory files: TUM and KITTI readers/writers, KITTI calibration and times.
#include <rasterslam/io/trajectory_io.h>
#include <unistd.h>

#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <system_error>

namespace rasterslam::io
{
namespace
{
/** Tolerance on |R^T R - I| (Frobenius): KITTI's files print 7 digits, so 1e-6 is normal. */
constexpr double kOrthoTol = 1e-3;

std::ifstream openForReading(const std::string& path, const char* what)
{
	std::ifstream in(path);
	if (!in)
	{
		throw std::runtime_error(std::string("cannot open ") + what + " '" + path +
		                         "': " + std::strerror(errno));
	}
	return in;
}

std::string where(const std::string& path, std::size_t line)
{
	return "'" + path + "' line " + std::to_string(line) + ": ";
}

/** Splits on blanks (and commas, which some TUM tools write) and parses every token as a
 *  finite double; throws naming the file and line. */
std::vector<double> parseNumbers(const std::string& text, const std::string& path, std::size_t line)
{
	std::string s = text;
	for (char& c : s)
	{
		if (c == ',' || c == '\t' || c == '\r')
			c = ' ';
	}
	std::istringstream ss(s);
	std::vector<double> out;
	std::string tok;
	while (ss >> tok)
	{
		// strtod (not from_chars) so that "1e+00", "+1" and "inf"/"nan" are all recognised,
		// the latter to be rejected with a precise message.
		char* end = nullptr;
		errno = 0;
		const double v = std::strtod(tok.c_str(), &end);
		if (end == tok.c_str() || *end != '\0')
		{
			throw std::runtime_error(where(path, line) + "column " +
			                         std::to_string(out.size() + 1) + ": expected a number, got '" +
			                         tok + "'");
		}
		if (!std::isfinite(v))
		{
			throw std::runtime_error(where(path, line) + "column " +
			                         std::to_string(out.size() + 1) +
			                         ": expected a finite number, got '" + tok + "'");
		}
		out.push_back(v);
	}
	return out;
}

bool isDataLine(const std::string& line)
{
	const auto p = line.find_first_not_of(" \t\r");
	return p != std::string::npos && line[p] != '#';
}

void checkRotation(const Eigen::Matrix3d& R, const std::string& path, std::size_t line)
{
	const double dev = (R.transpose() * R - Eigen::Matrix3d::Identity()).norm();
	if (!(dev <= kOrthoTol) || R.determinant() < 0)
	{
		std::ostringstream msg;
		msg << where(path, line) << "rotation is not orthonormal (|R^T R - I| = " << dev
		    << ", det = " << R.determinant() << "; expected a proper rotation)";
		throw std::runtime_error(msg.str());
	}
}

const char* formatName(TrajectoryFormat f)
{
	switch (f)
	{
		case TrajectoryFormat::Tum:
			return "TUM (8 columns: t x y z qx qy qz qw)";
		case TrajectoryFormat::Kitti:
			return "KITTI (12 columns: row-major 3x4)";
		default:
			return "TUM (8 columns) or KITTI (12 columns)";
	}
}

/** Shortest text that reads back to exactly the same double. */
void appendNumber(std::string& out, double v, std::chars_format fmt = std::chars_format::general)
{
	char buf[512];
	const auto r = std::to_chars(buf, buf + sizeof(buf), v, fmt);
	if (r.ec != std::errc())
		throw std::runtime_error("cannot format a number for a trajectory");
	out.append(buf, r.ptr);
}

}  // namespace

Trajectory loadTrajectory(const std::string& path, TrajectoryFormat fmt, TrajectoryFormat* detected)
{
	std::ifstream in = openForReading(path, "trajectory file");
	Trajectory traj;
	std::string text;
	std::size_t lineNo = 0;
	while (std::getline(in, text))
	{
		++lineNo;
		if (!isDataLine(text))
			continue;
		const std::vector<double> v = parseNumbers(text, path, lineNo);
		if (fmt == TrajectoryFormat::Auto)
		{
			// The first data line decides; later lines must agree with it.
			if (v.size() == 8)
				fmt = TrajectoryFormat::Tum;
			else if (v.size() == 12)
				fmt = TrajectoryFormat::Kitti;
		}
		const std::size_t want = fmt == TrajectoryFormat::Tum     ? 8
		                         : fmt == TrajectoryFormat::Kitti ? 12
		                                                          : 0;
		if (v.size() != want)
		{
			throw std::runtime_error(where(path, lineNo) + "expected " + formatName(fmt) +
			                         ", got " + std::to_string(v.size()) + " columns");
		}
		StampedPose sp;
		if (fmt == TrajectoryFormat::Tum)
		{
			sp.stamp = v[0];
			Eigen::Quaterniond q(v[7], v[4], v[5], v[6]);  // Eigen's order is (w, x, y, z)
			if (std::abs(q.norm() - 1.0) > kOrthoTol)
			{
				std::ostringstream msg;
				msg << where(path, lineNo) << "quaternion norm is " << q.norm()
				    << "; expected a unit quaternion (qx qy qz qw)";
				throw std::runtime_error(msg.str());
			}
			sp.pose.linear() = q.normalized().toRotationMatrix();
			sp.pose.translation() = Eigen::Vector3d(v[1], v[2], v[3]);
		}
		else
		{
			sp.stamp = static_cast<double>(traj.size());
			Eigen::Matrix3d R;
			R << v[0], v[1], v[2], v[4], v[5], v[6], v[8], v[9], v[10];
			checkRotation(R, path, lineNo);
			// Kept as read (not re-orthonormalised) so that files round-trip unchanged.
			sp.pose.linear() = R;
			sp.pose.translation() = Eigen::Vector3d(v[3], v[7], v[11]);
		}
		traj.push_back(sp);
	}
	if (in.bad())
		throw std::runtime_error("error reading trajectory file '" + path + "'");
	if (detected)
		*detected = fmt;
	return traj;
}

void saveTrajectoryTum(const std::string& path, const Trajectory& traj)
{
	writeFileAtomically(path, formatTrajectoryTum(traj));
}

void appendTumLine(std::string& out, const StampedPose& sp)
{
	// Stamps in fixed notation (1.7e9 s with its microseconds stays readable); every number is
	// the shortest text that reads back to the same double.
	appendNumber(out, sp.stamp, std::chars_format::fixed);
	const Eigen::Vector3d t = sp.pose.translation();
	const Eigen::Quaterniond q(sp.pose.rotation());
	for (double x : {t.x(), t.y(), t.z(), q.x(), q.y(), q.z(), q.w()})
	{
		out += ' ';
		appendNumber(out, x);
	}
	out += '\n';
}

std::string formatTrajectoryTum(const Trajectory& traj)
{
	std::string out = kTumHeader;
	for (const auto& sp : traj)
		appendTumLine(out, sp);
	return out;
}

void saveTrajectoryKitti(const std::string& path, const Trajectory& traj)
{
	writeFileAtomically(path, formatTrajectoryKitti(traj));
}

void appendKittiLine(std::string& out, const Eigen::Isometry3d& pose)
{
	const Eigen::Matrix4d M = pose.matrix();
	for (int r = 0; r < 3; ++r)
	{
		for (int c = 0; c < 4; ++c)
		{
			if (r || c)
				out += ' ';
			appendNumber(out, M(r, c));
		}
	}
	out += '\n';
}

std::string formatTrajectoryKitti(const Trajectory& traj)
{
	std::string out;
	for (const auto& sp : traj)
		appendKittiLine(out, sp.pose);
	return out;
}

Eigen::Isometry3d loadKittiCalibTr(const std::string& calibPath)
{
	std::ifstream in = openForReading(calibPath, "KITTI calibration file");
	std::string text;
	std::size_t lineNo = 0;
	while (std::getline(in, text))
	{
		++lineNo;
		const auto p = text.find_first_not_of(" \t");
		if (p == std::string::npos)
			continue;
		const auto colon = text.find(':', p);
		if (colon == std::string::npos)
			continue;
		const std::string key = text.substr(p, colon - p);
		if (key != "Tr" && key != "Tr_velo_to_cam")
			continue;
		const std::vector<double> v = parseNumbers(text.substr(colon + 1), calibPath, lineNo);
		if (v.size() != 12)
		{
			throw std::runtime_error(where(calibPath, lineNo) + "expected 12 numbers after '" +
			                         key + ":', got " + std::to_string(v.size()));
		}
		Eigen::Matrix3d R;
		R << v[0], v[1], v[2], v[4], v[5], v[6], v[8], v[9], v[10];
		checkRotation(R, calibPath, lineNo);
		Eigen::Isometry3d Tr = Eigen::Isometry3d::Identity();
		Tr.linear() = R;
		Tr.translation() = Eigen::Vector3d(v[3], v[7], v[11]);
		return Tr;
	}
	throw std::runtime_error("KITTI calibration file '" + calibPath +
	                         "' has no 'Tr:' line (Velodyne -> cam0, 12 numbers)");
}

std::vector<double> loadKittiTimes(const std::string& path)
{
	std::ifstream in = openForReading(path, "KITTI times file");
	std::vector<double> times;
	std::string text;
	std::size_t lineNo = 0;
	while (std::getline(in, text))
	{
		++lineNo;
		if (!isDataLine(text))
			continue;
		const std::vector<double> v = parseNumbers(text, path, lineNo);
		if (v.size() != 1)
		{
			throw std::runtime_error(where(path, lineNo) + "expected one number (seconds), got " +
			                         std::to_string(v.size()) + " columns");
		}
		times.push_back(v[0]);
	}
	return times;
}

Trajectory kittiCameraToVelodyne(const Trajectory& camPoses, const Eigen::Isometry3d& Tr)
{
	// P_velo = inv(Tr) * P_cam * Tr: express cam0's motion as the motion of the Velodyne. The
	// full inverse (not R^T): calib.txt's R is orthonormal only to ~1e-8.
	const Eigen::Isometry3d TrInv(Tr.inverse(Eigen::Affine).matrix());
	Trajectory out = camPoses;
	for (auto& sp : out)
		sp.pose = TrInv * sp.pose * Tr;
	return out;
}

void writeFileAtomically(const std::string& path, const std::string& contents)
{
	namespace fs = std::filesystem;
	const fs::path target(path);
	// Same folder as the target so that the rename never crosses file systems.
	fs::path tmp = target;
	tmp += ".tmp-" + std::to_string(::getpid());
	{
		std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
		if (!out)
		{
			throw std::runtime_error("cannot write '" + path + "' (temporary file '" +
			                         tmp.string() + "'): " + std::strerror(errno));
		}
		out.write(contents.data(), static_cast<std::streamsize>(contents.size()));
		out.flush();
		if (!out)
		{
			std::error_code ec;
			fs::remove(tmp, ec);
			throw std::runtime_error("error writing '" + path + "' (disk full?)");
		}
	}
	std::error_code ec;
	fs::rename(tmp, target, ec);
	if (ec)
	{
		std::error_code ignored;
		fs::remove(tmp, ignored);
		throw std::runtime_error("cannot rename the temporary file onto '" + path +
		                         "': " + ec.message());
	}
}

}  // namespace rasterslam::io
