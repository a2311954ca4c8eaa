// Which scans of a session revisit places of earlier sessions: the truth a multi-session
// benchmark scores relocalization and loops to earlier sessions against.
#pragma once

#include <rasterslam/io/trajectory_io.h>

#include <cstddef>
#include <string>
#include <vector>

namespace rasterslam::sim
{
/** Scan `scan` of the session passes within `distance_m` of scan `earlierScan` of earlier
 *  session `session` (an index into the list of earlier sessions): the nearest earlier pose
 *  over all of them. */
struct Revisit
{
	std::size_t scan = 0;
	double stamp = 0;
	std::size_t session = 0;
	std::size_t earlierScan = 0;
	double earlierStamp = 0;
	/** Distance between the two sensor positions (3D), metres. */
	double distance_m = 0;
	/** Heading difference in [0, 180] degrees: near 180 is the place driven the other way. */
	double yawDiff_deg = 0;
};

/** Every scan of `session` whose nearest pose in `earlier` is within `radius_m`, in scan
 *  order. Poses are in one world frame (a simulated town's). */
std::vector<Revisit> findRevisits(const io::Trajectory& session,
                                  const std::vector<io::Trajectory>& earlier, double radius_m);

/** The revisits as text: a header naming the columns and the radius, then one line per
 *  revisit: scan stamp session earlier_scan earlier_stamp distance_m yaw_diff_deg, where
 *  session is the name given for that earlier session. */
std::string formatRevisits(const std::vector<Revisit>& revisits,
                           const std::vector<std::string>& sessionNames, double radius_m);

}  // namespace rasterslam::sim
