// Conversions between MRPT poses and Eigen isometries.
#pragma once

#include <mrpt/math/CMatrixFixed.h>
#include <mrpt/poses/CPose3D.h>

#include <Eigen/Geometry>

namespace rasterslam
{
inline mrpt::poses::CPose3D toPose(const Eigen::Isometry3d& T)
{
	mrpt::math::CMatrixDouble44 M;
	for (int r = 0; r < 4; r++)
		for (int c = 0; c < 4; c++)
			M(r, c) = T.matrix()(r, c);
	return mrpt::poses::CPose3D::FromHomogeneousMatrix(M);
}

inline Eigen::Isometry3d toIsometry(const mrpt::poses::CPose3D& p)
{
	Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
	const auto M = p.getHomogeneousMatrixVal<mrpt::math::CMatrixDouble44>();
	for (int r = 0; r < 4; r++)
		for (int c = 0; c < 4; c++)
			T.matrix()(r, c) = M(r, c);
	return T;
}

}  // namespace rasterslam
