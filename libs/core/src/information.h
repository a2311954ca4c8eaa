// Information matrices of the engine's and map merge's pose-graph edges (not a public header).
#pragma once

#include <mrpt/math/CMatrixFixed.h>

#include <cmath>

namespace rasterslam
{
/** The information of an edge good to `m` metres on each axis of its translation and `deg`
 *  degrees about each axis of its rotation (MRPT's order: x, y, z, then the rotation). */
inline mrpt::math::CMatrixDouble66 diagonalInformation(double m, double deg)
{
	mrpt::math::CMatrixDouble66 info;
	info.setZero();
	const double rad = deg * M_PI / 180;
	for (int a = 0; a < 3; a++)
	{
		info(a, a) = 1.0 / (m * m);
		info(a + 3, a + 3) = 1.0 / (rad * rad);
	}
	return info;
}
}  // namespace rasterslam
