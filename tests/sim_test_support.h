// Helpers shared by the simulator's tests.
#pragma once

#include <rasterslam/sim/simulator.h>

#include <cstddef>
#include <istream>
#include <sstream>
#include <string>
#include <vector>

namespace rasterslam::test
{
/** Options that make every range exact: no noise, no dropouts, no rounding. */
inline sim::SimulatorOptions exactSimOptions()
{
	sim::SimulatorOptions o;
	o.noise.range_sigma_m = 0;
	o.noise.dropout_prob = 0;
	o.noise.intensity_sigma = 0;
	o.point_resolution_m = 0;
	return o;
}

/** One line of a revisit file as `sim::formatRevisits` writes it. */
struct RevisitLine
{
	std::size_t scan = 0, earlierScan = 0;
	double stamp = 0, earlierStamp = 0, distance_m = -1, yaw_deg = -1;
	std::string session, text;
	bool parsed = false;
};

/** Every line of a revisit file but comments and blank lines; `parsed` is false where a line
 *  does not have the seven fields. */
inline std::vector<RevisitLine> parseRevisits(std::istream& in)
{
	std::vector<RevisitLine> out;
	std::string line;
	while (std::getline(in, line))
	{
		if (line.empty() || line[0] == '#')
			continue;
		RevisitLine r;
		r.text = line;
		std::istringstream f(line);
		r.parsed = static_cast<bool>(f >> r.scan >> r.stamp >> r.session >> r.earlierScan >>
		                             r.earlierStamp >> r.distance_m >> r.yaw_deg);
		out.push_back(r);
	}
	return out;
}
}  // namespace rasterslam::test
