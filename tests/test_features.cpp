// Features of the tracking: the closed-form rigid fit and its RANSAC, the information matrix,
// mutual Hamming matching with its spatial gate, and ORB over a grid.
#include <rasterslam/features/icp.h>
#include <rasterslam/features/matcher.h>
#include <rasterslam/features/orb_extractor.h>
#include <rasterslam/features/planar_search.h>
#include <rasterslam/features/rigid_ransac.h>
#include <rasterslam/io/kitti.h>
#include <rasterslam/raster/elevation_image.h>
#include <rasterslam/raster/ground_plane.h>

#include <Eigen/Dense>
#include <algorithm>
#include <limits>
#include <numeric>
#include <opencv2/imgproc.hpp>
#include <random>
#include <set>

#include "test_support.h"

namespace
{
using namespace rasterslam;
constexpr double kDeg = 3.14159265358979323846 / 180.0;

Eigen::Isometry3d motion(double yawDeg, const Eigen::Vector3d& t, double pitchDeg = 0,
                         double rollDeg = 0)
{
	Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
	T.linear() = (Eigen::AngleAxisd(yawDeg * kDeg, Eigen::Vector3d::UnitZ()) *
	              Eigen::AngleAxisd(pitchDeg * kDeg, Eigen::Vector3d::UnitY()) *
	              Eigen::AngleAxisd(rollDeg * kDeg, Eigen::Vector3d::UnitX()))
	                 .toRotationMatrix();
	T.translation() = t;
	return T;
}

double rotationErrorDeg(const Eigen::Isometry3d& A, const Eigen::Isometry3d& B)
{
	return Eigen::AngleAxisd(A.linear().transpose() * B.linear()).angle() / kDeg;
}

/** 500 points in a 100 x 100 x 10 m box, q = T p + N(0, 0.03) for the inliers, and a random
 *  point of the box instead of q for a fraction `outlierRatio` of the pairs. */
struct Synthetic
{
	std::vector<Eigen::Vector3f> p, q;
	std::vector<char> inlier;
	Eigen::Isometry3d T = motion(10.0, {1.5, -0.4, 0.1});
};
Synthetic makePairs(uint32_t seed, double outlierRatio, int n = 500)
{
	Synthetic s;
	std::mt19937 rng(seed);
	std::uniform_real_distribution<float> xy(-50, 50), z(-5, 5), u(0, 1);
	std::normal_distribution<float> noise(0, 0.03f);
	const Eigen::Isometry3f T = s.T.cast<float>();
	for (int i = 0; i < n; i++)
	{
		const Eigen::Vector3f a(xy(rng), xy(rng), z(rng));
		s.p.push_back(a);
		if (u(rng) < outlierRatio)
		{
			s.q.emplace_back(xy(rng), xy(rng), z(rng));
			s.inlier.push_back(0);
		}
		else
		{
			s.q.push_back(T * a + Eigen::Vector3f(noise(rng), noise(rng), noise(rng)));
			s.inlier.push_back(1);
		}
	}
	return s;
}

cv::Mat randomDescriptors(int rows, uint32_t seed)
{
	std::mt19937 rng(seed);
	cv::Mat d(rows, 32, CV_8U);
	for (int r = 0; r < rows; r++)
		for (int c = 0; c < 32; c++)
			d.at<uint8_t>(r, c) = static_cast<uint8_t>(rng() & 0xFF);
	return d;
}
}  // namespace

TEST(RigidFit, ExactOnNoiselessPairs)
{
	const Eigen::Isometry3d T = motion(-37.0, {4.0, 2.5, -0.7}, 3.0, -5.0);
	std::mt19937 rng(3);
	std::uniform_real_distribution<float> d(-20, 20);
	std::vector<Eigen::Vector3f> p, q;
	for (int i = 0; i < 30; i++)
	{
		p.emplace_back(d(rng), d(rng), d(rng) / 4);
		q.push_back((T * p.back().cast<double>()).cast<float>());
	}
	std::vector<int> idx(30);
	std::iota(idx.begin(), idx.end(), 0);
	Eigen::Isometry3d est;
	ASSERT_TRUE(features::fitRigid(p, q, idx, est));
	EXPECT_LT((est.translation() - T.translation()).norm(), 1e-4);
	EXPECT_LT(rotationErrorDeg(est, T), 1e-4);
	// Three pairs determine it too; two do not.
	ASSERT_TRUE(features::fitRigid(p, q, {0, 1, 2}, est));
	EXPECT_LT((est.translation() - T.translation()).norm(), 1e-3);
	EXPECT_FALSE(features::fitRigid(p, q, {0, 1}, est));
}

TEST(RigidRansac, RecoversMotionDespiteOutliers)
{
	const auto s = makePairs(42, 0.3);
	const int nIn = static_cast<int>(std::count(s.inlier.begin(), s.inlier.end(), 1));
	ASSERT_GT(nIn, 300);
	ASSERT_LT(nIn, 400);
	const auto r = features::ransacRigid(s.p, s.q, features::RansacParams(), 7);
	ASSERT_TRUE(r.ok);
	// Measured: 2.9 mm and 0.004 deg (17 iterations).
	EXPECT_LT((r.T.translation() - s.T.translation()).norm(), 0.02);
	EXPECT_LT(rotationErrorDeg(r.T, s.T), 0.1);
	int trueIn = 0, falseIn = 0;
	for (const int i : r.inliers)
		(s.inlier[static_cast<std::size_t>(i)] ? trueIn : falseIn)++;
	EXPECT_GE(trueIn, 0.95 * nIn);  // measured: all 355 true inliers, none of the 145 outliers
	EXPECT_LT(falseIn, 0.02 * (500 - nIn));
	EXPECT_EQ(std::set<int>(r.inliers.begin(), r.inliers.end()).size(), r.inliers.size());
	EXPECT_NEAR(r.rmse_m, 0.03 * std::sqrt(3.0), 0.015);  // 3D norm of the noise
	EXPECT_LE(r.iterations, features::RansacParams().maxIterations);

	// Deterministic for a seed.
	const auto r2 = features::ransacRigid(s.p, s.q, features::RansacParams(), 7);
	EXPECT_EQ(r2.inliers, r.inliers);
	EXPECT_TRUE(r2.T.isApprox(r.T, 0));
	EXPECT_EQ(r2.iterations, r.iterations);
}

TEST(RigidRansac, NoConsensusIsNotOk)
{
	// All pairs random: no motion explains them.
	const auto s = makePairs(5, 1.0);
	for (uint32_t seed : {1u, 2u, 3u})
	{
		const auto r = features::ransacRigid(s.p, s.q, features::RansacParams(), seed);
		EXPECT_FALSE(r.ok) << "seed " << seed << ": " << r.inliers.size() << " inliers";
		EXPECT_LT(r.inliers.size(), 20u);
	}
	// Fewer than 3 pairs, or sets of different sizes.
	const std::vector<Eigen::Vector3f> two = {{0, 0, 0}, {1, 0, 0}};
	EXPECT_FALSE(features::ransacRigid(two, two, features::RansacParams(), 1).ok);
	EXPECT_FALSE(features::ransacRigid({}, {}, features::RansacParams(), 1).ok);
	auto q = s.p;
	q.pop_back();
	EXPECT_FALSE(features::ransacRigid(s.p, q, features::RansacParams(), 1).ok);
	// Collinear points leave the rotation about their line free: no sample is accepted.
	std::vector<Eigen::Vector3f> line;
	for (int i = 0; i < 50; i++)
		line.emplace_back(float(i), 0, 0);
	EXPECT_FALSE(features::ransacRigid(line, line, features::RansacParams(), 1).ok);
	// Fewer agreeing pairs than minInliers.
	const auto few = makePairs(9, 0.0, 15);
	EXPECT_FALSE(features::ransacRigid(few.p, few.q, features::RansacParams(), 1).ok);
	features::RansacParams loose;
	loose.minInliers = 10;
	EXPECT_TRUE(features::ransacRigid(few.p, few.q, loose, 1).ok);
}

TEST(RigidRansac, RobustRefitWeighsHeightsAndMismatchesLess)
{
	const Eigen::Isometry3d T = motion(1.5, {1.2, 0.1, 0.02}, 0.3, -0.2);
	const auto planarError = [&T](const Eigen::Isometry3d& E)
	{ return (E.translation() - T.translation()).head<2>().norm(); };
	std::mt19937 rng(17);
	std::uniform_real_distribution<double> angle(-M_PI, M_PI), range(3, 40), height(0.5, 6),
	    unit(0, 1);
	std::normal_distribution<double> noise(0, 0.02);
	// Street features: x and y good to 2 cm; a fifth of the pairs matched to the next of a
	// row of alike things along the street (0.2 m on in x), still within the RANSAC threshold.
	std::vector<Eigen::Vector3f> p, q;
	for (int i = 0; i < 300; i++)
	{
		const double a = angle(rng), r = range(rng);
		const Eigen::Vector3d pi(r * std::cos(a), r * std::sin(a), height(rng));
		Eigen::Vector3d qi = T * pi + Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
		if (unit(rng) < 0.2)
			qi.x() += 0.2;
		p.push_back(pi.cast<float>());
		q.push_back(qi.cast<float>());
	}
	const features::RansacParams prm;
	const auto plain = features::ransacRigid(p, q, prm, 5);
	ASSERT_TRUE(plain.ok);
	ASSERT_GT(plain.inliers.size(), 280u);  // the shifted pairs are inliers too

	// Defaults (z weighed as x and y, no loss): the least-squares fit of the inliers again.
	auto same = plain;
	ASSERT_TRUE(features::refitRobust(p, q, features::RobustRefitParams(), prm, same));
	Eigen::Isometry3d ls;
	ASSERT_TRUE(features::fitRigid(p, q, plain.inliers, ls));
	EXPECT_LT((same.T.translation() - ls.translation()).norm(), 1e-4);
	EXPECT_LT(rotationErrorDeg(same.T, ls), 1e-4);

	// The Cauchy loss discounts the mismatched fifth, which least squares follows by 4 cm.
	features::RobustRefitParams refit;
	refit.cauchy_m = 0.1;
	auto robust = plain;
	ASSERT_TRUE(features::refitRobust(p, q, refit, prm, robust));
	ASSERT_TRUE(robust.ok);
	EXPECT_GT(planarError(plain.T), 0.03);
	EXPECT_LT(planarError(robust.T), 0.5 * planarError(plain.T))
	    << planarError(robust.T) << " against " << planarError(plain.T);
	EXPECT_LT(rotationErrorDeg(robust.T, T), 0.05);

	// Heights that no rigid motion explains (a shear: 1 cm a metre of x) tilt a fit that
	// weighs them, and the tilt moves x; weighed a thousandth, they leave x and y alone.
	std::vector<Eigen::Vector3f> sheared;
	features::RigidResult all;
	all.ok = true;
	for (int i = 0; i < 300; i++)
	{
		const Eigen::Vector3d pi = p[i].cast<double>();
		Eigen::Vector3d qi = T * pi;
		qi.z() -= 0.01 * pi.x();
		sheared.push_back(qi.cast<float>());
		all.inliers.push_back(i);
	}
	auto alike = all, light = all;
	refit = features::RobustRefitParams();
	ASSERT_TRUE(features::refitRobust(p, sheared, refit, prm, alike));
	refit.zWeight = 0.001;
	ASSERT_TRUE(features::refitRobust(p, sheared, refit, prm, light));
	EXPECT_GT(planarError(alike.T), 0.01);
	EXPECT_LT(planarError(light.T), 0.2 * planarError(alike.T))
	    << planarError(light.T) << " against " << planarError(alike.T);

	// A fit that is not ok, or of fewer than 6 inliers, is left alone; so is one whose refit
	// would keep fewer than minInliers: RANSAC's fit stands, still ok.
	refit.zWeight = 1;
	refit.cauchy_m = 0.1;
	auto notOk = plain;
	notOk.ok = false;
	EXPECT_FALSE(features::refitRobust(p, q, refit, prm, notOk));
	EXPECT_TRUE(notOk.T.isApprox(plain.T, 0));
	auto five = plain;
	five.inliers.resize(5);
	EXPECT_FALSE(features::refitRobust(p, q, refit, prm, five));
	EXPECT_TRUE(five.T.isApprox(plain.T, 0));
	features::RansacParams strict = prm;
	strict.minInliers = static_cast<int>(p.size()) + 1;
	auto kept = plain;
	EXPECT_FALSE(features::refitRobust(p, q, refit, strict, kept));
	EXPECT_TRUE(kept.ok);
	EXPECT_TRUE(kept.T.isApprox(plain.T, 0));
	EXPECT_EQ(kept.inliers, plain.inliers);
}

TEST(RigidRansac, PointToPointInformation)
{
	std::mt19937 rng(11);
	std::uniform_real_distribution<float> d(-30, 30), dz(-3, 3);
	std::vector<Eigen::Vector3f> pts;
	for (int i = 0; i < 200; i++)
		pts.emplace_back(d(rng), d(rng), dz(rng));
	std::vector<int> idx(pts.size());
	std::iota(idx.begin(), idx.end(), 0);
	const auto I = features::pointToPointInformation(pts, idx, 0.1);
	EXPECT_TRUE(I.isApprox(I.transpose(), 1e-12));
	const Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 6, 6>> es(I);
	EXPECT_GT(es.eigenvalues().minCoeff(), 0);
	// Translation block: n / sigma^2 on the diagonal.
	EXPECT_NEAR(I(0, 0), 200 / 0.01, 1e-6);
	EXPECT_NEAR(I(2, 2), 200 / 0.01, 1e-6);

	// Points along x (long) and y (short) on the plane z = 0: MRPT order x y z yaw pitch roll.
	// yaw ~ sum(x^2 + y^2), pitch (about y) ~ sum(x^2), roll (about x) ~ sum(y^2).
	std::vector<Eigen::Vector3f> flat;
	double sx2 = 0, sy2 = 0;
	for (int i = 0; i < 100; i++)
	{
		flat.emplace_back(d(rng), d(rng) / 10, 0);
		sx2 += double(flat.back().x()) * flat.back().x();
		sy2 += double(flat.back().y()) * flat.back().y();
	}
	std::vector<int> all(100);
	std::iota(all.begin(), all.end(), 0);
	const auto F = features::pointToPointInformation(flat, all, 1.0);
	EXPECT_NEAR(F(3, 3), sx2 + sy2, 1e-6 * (sx2 + sy2));  // yaw
	EXPECT_NEAR(F(4, 4), sx2, 1e-6 * sx2);                // pitch
	EXPECT_NEAR(F(5, 5), sy2, 1e-6 * sx2);                // roll
	EXPECT_GT(F(3, 3), 10 * F(5, 5));
	// Only the listed points count, and sigma scales as 1 / sigma^2.
	const auto half = features::pointToPointInformation(flat, {0, 1, 2}, 2.0);
	EXPECT_NEAR(half(0, 0), 3 / 4.0, 1e-12);
}

TEST(Matcher, IdenticalAndShuffledSets)
{
	const cv::Mat A = randomDescriptors(200, 1);
	features::MatchParams mp;
	auto m = features::matchMutual(A, A, mp);
	ASSERT_EQ(m.size(), 200u);
	for (int i = 0; i < 200; i++)
	{
		EXPECT_EQ(m[i].a, i);
		EXPECT_EQ(m[i].b, i);
		EXPECT_EQ(m[i].distance, 0);
	}
	std::vector<int> perm(200);
	std::iota(perm.begin(), perm.end(), 0);
	std::shuffle(perm.begin(), perm.end(), std::mt19937(2));
	cv::Mat B(200, 32, CV_8U);
	for (int i = 0; i < 200; i++)
		A.row(i).copyTo(B.row(perm[i]));
	m = features::matchMutual(A, B, mp);
	ASSERT_EQ(m.size(), 200u);
	for (const auto& x : m)
		EXPECT_EQ(x.b, perm[x.a]);
	EXPECT_TRUE(features::matchMutual(A, cv::Mat(0, 32, CV_8U), mp).empty());
}

/** matchMutual without positions as it was written first: pair after pair. */
std::vector<features::Match> pairAfterPair(const cv::Mat& A, const cv::Mat& B,
                                           const features::MatchParams& p)
{
	constexpr int kInf = std::numeric_limits<int>::max();
	std::vector<int> bestA(A.rows, -1), distA(A.rows, kInf), secondA(A.rows, kInf);
	std::vector<int> bestB(B.rows, -1), distB(B.rows, kInf);
	for (int i = 0; i < A.rows; i++)
		for (int j = 0; j < B.rows; j++)
		{
			const int d = features::hamming32(A.ptr<uint8_t>(i), B.ptr<uint8_t>(j));
			if (d < distA[i])
			{
				secondA[i] = distA[i];
				distA[i] = d;
				bestA[i] = j;
			}
			else if (d < secondA[i])
				secondA[i] = d;
			if (d < distB[j])
			{
				distB[j] = d;
				bestB[j] = i;
			}
		}
	std::vector<features::Match> out;
	for (int i = 0; i < A.rows; i++)
	{
		const int j = bestA[i];
		if (j < 0 || bestB[j] != i || distA[i] > p.maxDistance)
			continue;
		if (p.ratio < 1.0f && secondA[i] != kInf && distA[i] >= p.ratio * secondA[i])
			continue;
		out.push_back({i, j, distA[i]});
	}
	return out;
}

TEST(Matcher, EveryKernelMatchesAsPairAfterPair)
{
	// Sets of every size around the kernels' 16 lanes, from descriptors with few set bits
	// (many equal distances, so that the ties decide) and from random ones, with and without
	// the ratio test and the distance bound.
	std::mt19937 rng(77);
	auto sparse = [&](int n)
	{
		cv::Mat d(n, 32, CV_8U, cv::Scalar(0));
		std::uniform_int_distribution<int> bit(0, 255);
		for (int i = 0; i < n; i++)
			for (int k = 0; k < 3; k++)
			{
				const int b = bit(rng);
				d.at<uint8_t>(i, b / 8) |= static_cast<uint8_t>(1u << (b % 8));
			}
		return d;
	};
	features::MatchParams plain, strict;
	plain.maxDistance = 256;
	strict.maxDistance = 40;
	strict.ratio = 0.8f;
	std::size_t compared = 0, matched = 0;
	struct Restore
	{
		~Restore() { features::forcePortableMatcher(false); }
	} restore;
	for (const bool portable : {true, false})
	{
		features::forcePortableMatcher(portable);
		SCOPED_TRACE(features::matcherKernel());
		if (!portable)
			std::printf("kernel on this processor: %s\n", features::matcherKernel());
		for (const int na : {1, 7, 16, 33, 200})
			for (const int nb : {1, 2, 15, 16, 17, 31, 250})
				for (const bool few : {true, false})
				{
					const cv::Mat A = few ? sparse(na) : randomDescriptors(na, rng());
					cv::Mat B = few ? sparse(nb) : randomDescriptors(nb, rng());
					if (!few)  // some true pairs among the random ones
						for (int i = 0; i < std::min(na, nb); i += 3)
							A.row(i).copyTo(B.row(nb - 1 - i));
					for (const auto* p : {&plain, &strict})
					{
						const auto got = features::matchMutual(A, B, *p);
						const auto want = pairAfterPair(A, B, *p);
						ASSERT_EQ(got.size(), want.size()) << na << " x " << nb;
						for (std::size_t k = 0; k < got.size(); k++)
						{
							EXPECT_EQ(got[k].a, want[k].a);
							EXPECT_EQ(got[k].b, want[k].b);
							EXPECT_EQ(got[k].distance, want[k].distance);
						}
						++compared;
						matched += got.size();
					}
				}
	}
	EXPECT_EQ(compared, 2u * 5 * 7 * 2 * 2);
	EXPECT_GT(matched, 1000u);  // the comparisons were about matches, not empty lists
}

// The direct index's matching: pairs in different groups are never compared.
TEST(Matcher, GroupedComparesOnlyWithinAGroup)
{
	const cv::Mat A = randomDescriptors(100, 3);
	features::MatchParams mp;
	std::vector<uint32_t> ga(100), gb(100);
	for (uint32_t i = 0; i < 100; i++)
		ga[i] = gb[i] = i % 7;
	// Same groups: every descriptor finds itself.
	auto m = features::matchMutualGrouped(A, A, mp, ga, gb);
	ASSERT_EQ(m.size(), 100u);
	for (const auto& x : m)
		EXPECT_EQ(x.a, x.b);
	// Every third feature of B put in another group: those lose their twin, and with no
	// distance limit match some other descriptor of their new group or nothing, never the
	// twin.
	for (uint32_t i = 0; i < 100; i += 3)
		gb[i] = 100 + i;
	m = features::matchMutualGrouped(A, A, mp, ga, gb);
	std::size_t same = 0;
	for (const auto& x : m)
	{
		EXPECT_EQ(ga[static_cast<std::size_t>(x.a)], gb[static_cast<std::size_t>(x.b)]);
		same += x.a == x.b;
	}
	EXPECT_EQ(same, 100u - 34u);
	// Groups of the wrong length are refused.
	EXPECT_ANY_THROW(features::matchMutualGrouped(A, A, mp, ga, std::vector<uint32_t>(5)));
}

TEST(Matcher, MaxDistanceRejectsFarPairs)
{
	const cv::Mat A = randomDescriptors(100, 3);
	cv::Mat B = A.clone();
	std::mt19937 rng(4);
	// Rows 0..49: 10 bits flipped (kept); rows 50..99: 40 bits flipped (beyond 30, rejected).
	for (int r = 0; r < 100; r++)
	{
		std::vector<int> bits(256);
		std::iota(bits.begin(), bits.end(), 0);
		std::shuffle(bits.begin(), bits.end(), rng);
		for (int k = 0; k < (r < 50 ? 10 : 40); k++)
			B.at<uint8_t>(r, bits[k] / 8) ^= uint8_t(1u << (bits[k] % 8));
	}
	features::MatchParams mp;
	mp.maxDistance = 30;
	const auto m = features::matchMutual(A, B, mp);
	ASSERT_EQ(m.size(), 50u);
	for (const auto& x : m)
	{
		EXPECT_LT(x.a, 50);
		EXPECT_EQ(x.a, x.b);
		EXPECT_EQ(x.distance, 10);
	}
	mp.maxDistance = 64;
	EXPECT_EQ(features::matchMutual(A, B, mp).size(), 100u);
}

TEST(Matcher, GateExcludesPairsFarApartInSpace)
{
	const cv::Mat A = randomDescriptors(100, 5);
	std::mt19937 rng(6);
	std::uniform_real_distribution<float> d(-40, 40);
	std::vector<Eigen::Vector3f> posA, posB;
	for (int i = 0; i < 100; i++)
	{
		posA.emplace_back(d(rng), d(rng), d(rng) / 10);
		// Even rows 1 m away from their twin (inside a 3 m gate), odd rows 10 m away.
		posB.push_back(posA.back() + Eigen::Vector3f(i % 2 ? 10.0f : 0.6f, i % 2 ? 0 : 0.8f, 0));
	}
	features::MatchParams mp;
	mp.gateRadius_m = 3;
	const auto m = features::matchMutual(A, A, mp, &posA, &posB);
	std::set<int> matched;
	for (const auto& x : m)
	{
		EXPECT_LE((posA[x.a] - posB[x.b]).norm(), 3.0f);
		EXPECT_EQ(x.a, x.b);
		matched.insert(x.a);
	}
	for (int i = 0; i < 100; i += 2)
		EXPECT_TRUE(matched.count(i)) << "row " << i;
	EXPECT_EQ(matched.size(), 50u);
	// Without the gate (radius 0, or no positions) all are matched.
	mp.gateRadius_m = 0;
	EXPECT_EQ(features::matchMutual(A, A, mp, &posA, &posB).size(), 100u);
	mp.gateRadius_m = 3;
	EXPECT_EQ(features::matchMutual(A, A, mp).size(), 100u);
}

/** A black image with `rects` filled rectangles (sides 5 to `maxSide` px, grey levels
 *  `greyLo` to `greyHi`) at random places drawn from `rng`: corners for ORB. */
cv::Mat texturedImage(int width, int height, int rects, int maxSide, int greyLo, int greyHi,
                      std::mt19937& rng)
{
	cv::Mat img(height, width, CV_8UC1, cv::Scalar(0));
	std::uniform_int_distribution<int> x(0, width - 1), y(0, height - 1), s(5, maxSide),
	    g(greyLo, greyHi);
	for (int i = 0; i < rects; i++)
	{
		const cv::Point a(x(rng), y(rng));
		cv::rectangle(img, a, a + cv::Point(s(rng), s(rng)), cv::Scalar(g(rng)), cv::FILLED);
	}
	return img;
}

TEST(Orb, ExtractorTakesAnyFeatureCount)
{
	// fuzz_config found numFeatures * 3 overflowing an int (undefined behaviour: the sanitizer
	// suite aborts on it). The count of corners detected saturates; the extraction works.
	std::mt19937 rng(9);
	const cv::Mat img = texturedImage(320, 240, 150, 30, 40, 255, rng);
	features::OrbParams p;
	p.numFeatures = std::numeric_limits<int>::max() / 2;
	features::OrbExtractor orb(p);
	std::vector<cv::KeyPoint> kps;
	cv::Mat desc;
	orb.extract(img, kps, desc);
	EXPECT_GT(kps.size(), 100u);
	EXPECT_EQ(desc.rows, static_cast<int>(kps.size()));
}

TEST(Orb, ExtractorOnATexturedImage)
{
	std::mt19937 rng(8);
	const cv::Mat img = texturedImage(640, 480, 400, 40, 40, 255, rng);
	features::OrbParams p;
	p.numFeatures = 500;
	features::OrbExtractor orb(p);
	std::vector<cv::KeyPoint> kps;
	cv::Mat desc;
	orb.extract(img, kps, desc);
	EXPECT_LE(kps.size(), 500u);
	EXPECT_GT(kps.size(), 300u);
	EXPECT_EQ(desc.rows, static_cast<int>(kps.size()));
	EXPECT_EQ(desc.cols, 32);
	EXPECT_EQ(desc.type(), CV_8U);
	EXPECT_GE(orb.lastThreshold(), p.minFastThreshold);
	EXPECT_LE(orb.lastThreshold(), p.fastThreshold);
	for (const auto& k : kps)
	{
		EXPECT_GE(k.pt.x, 0);
		EXPECT_LT(k.pt.x, 640);
		EXPECT_GE(k.pt.y, 0);
		EXPECT_LT(k.pt.y, 480);
	}
	// Same image, same result.
	std::vector<cv::KeyPoint> kps2;
	cv::Mat desc2;
	orb.extract(img, kps2, desc2);
	ASSERT_EQ(kps2.size(), kps.size());
	EXPECT_EQ(cv::norm(desc, desc2, cv::NORM_HAMMING), 0);
	// Low contrast (steps of 8 to 14 grey levels): the FAST threshold is lowered.
	const cv::Mat faint = texturedImage(640, 480, 400, 40, 8, 14, rng);
	orb.extract(faint, kps, desc);
	EXPECT_LT(orb.lastThreshold(), p.fastThreshold);
	EXPECT_GT(kps.size(), 100u);
	EXPECT_EQ(desc.rows, static_cast<int>(kps.size()));
	// A black image has nothing.
	orb.extract(cv::Mat(480, 640, CV_8UC1, cv::Scalar(0)), kps, desc);
	EXPECT_TRUE(kps.empty());
	EXPECT_EQ(desc.rows, 0);
}

/** What OrbExtractor::extract gave before it searched from the last image's threshold: every
 *  threshold from the highest, halved down to the lowest, until one finds enough corners. */
struct EveryThreshold
{
	features::OrbParams p;
	cv::Ptr<cv::ORB> orb;
	std::size_t detections = 0;
	explicit EveryThreshold(const features::OrbParams& params) : p(params)
	{
		orb = cv::ORB::create(3 * p.numFeatures, p.scaleFactor, p.levels, p.edgeThreshold, 0, 2,
		                      cv::ORB::HARRIS_SCORE, p.patchSize, p.fastThreshold);
	}
	int extract(const cv::Mat& img, std::vector<cv::KeyPoint>& kps, cv::Mat& desc)
	{
		int thr = p.fastThreshold;
		for (;; thr = std::max(p.minFastThreshold, thr / 2))
		{
			orb->setFastThreshold(thr);
			kps.clear();
			orb->detect(img, kps);
			++detections;
			if (static_cast<int>(kps.size()) >= p.numFeatures || thr <= p.minFastThreshold)
				break;
		}
		kps = features::distributeOverGrid(kps, img.cols, img.rows, p.gridCols, p.gridRows,
		                                   p.numFeatures);
		orb->compute(img, kps, desc);
		return thr;
	}
};

/** The same keypoints (position, size, angle, response, level) and descriptors. */
void expectSameFeatures(const std::vector<cv::KeyPoint>& a, const cv::Mat& da,
                        const std::vector<cv::KeyPoint>& b, const cv::Mat& db)
{
	ASSERT_EQ(a.size(), b.size());
	for (std::size_t i = 0; i < a.size(); i++)
	{
		EXPECT_EQ(a[i].pt, b[i].pt) << i;
		EXPECT_EQ(a[i].size, b[i].size) << i;
		EXPECT_EQ(a[i].angle, b[i].angle) << i;
		EXPECT_EQ(a[i].response, b[i].response) << i;
		EXPECT_EQ(a[i].octave, b[i].octave) << i;
	}
	ASSERT_EQ(da.size(), db.size());
	if (!da.empty())
	{
		EXPECT_EQ(cv::norm(da, db, cv::NORM_HAMMING), 0);
	}
}

TEST(Orb, SearchFromTheLastThresholdGivesWhatTryingEveryThresholdGives)
{
	// Images whose corners end the search at each threshold, in an order that walks it up and
	// down (strong, faint, fainter, black, strong again), then a real drive: the KITTI
	// sample's elevation images, which mostly end at the lowest threshold.
	std::mt19937 rng(31);
	std::vector<cv::Mat> images;
	const int contrast[][2] = {{40, 255}, {8, 14}, {5, 8},   {0, 0},    {40, 255}, {5, 8},
	                           {5, 8},    {8, 14}, {12, 20}, {40, 255}, {40, 255}};
	for (const auto& c : contrast)
		images.push_back(c[1] == 0 ? cv::Mat(480, 640, CV_8UC1, cv::Scalar(0))
		                           : texturedImage(640, 480, 900, 30, c[0], c[1], rng));
	features::OrbParams p;
	p.numFeatures = 1000;
	features::OrbExtractor orb(p);
	EveryThreshold ref(p);
	EXPECT_EQ(orb.thresholds(), (std::vector<int>{20, 10, 5}));
	std::set<int> ended;
	for (std::size_t i = 0; i < images.size(); i++)
	{
		SCOPED_TRACE("image " + std::to_string(i));
		std::vector<cv::KeyPoint> a, b;
		cv::Mat da, db;
		orb.extract(images[i], a, da);
		const int thr = ref.extract(images[i], b, db);
		EXPECT_EQ(orb.lastThreshold(), thr);
		ended.insert(thr);
		expectSameFeatures(a, da, b, db);
	}
	EXPECT_EQ(ended, (std::set<int>{20, 10, 5}));  // every threshold was the answer somewhere

	RASTERSLAM_REQUIRE_SHARED_DATA();
	features::OrbParams kp;  // the odometry's defaults: 2,000 features
	features::OrbExtractor kittiOrb(kp);
	EveryThreshold kittiRef(kp);
	raster::RasterParams rp;
	std::size_t images0 = 0;
	ended.clear();
	for (int i = 0; i < 101; i += 2)
	{
		char name[32];
		std::snprintf(name, sizeof(name), "%06d.bin", i);
		const auto pts = io::loadKittiBin(test::sharedData("kitti00-0000-0100/velodyne/") + name);
		RasterFrame f;
		raster::rasterizeElevation(pts, raster::fitGroundPlane(pts, raster::GroundParams(), 1), rp,
		                           f);
		const cv::Mat img = f.image.asCvMatRef();
		std::vector<cv::KeyPoint> a, b;
		cv::Mat da, db;
		kittiOrb.extract(img, a, da);
		const int thr = kittiRef.extract(img, b, db);
		EXPECT_EQ(kittiOrb.lastThreshold(), thr) << name;
		ended.insert(thr);
		expectSameFeatures(a, da, b, db);
		++images0;
	}
	EXPECT_GE(ended.size(), 2u);  // the drive's images do not all end at one threshold
	// What the search saves: trying every threshold detected 2.6 times an image here.
	std::printf("KITTI, %zu images: %zu detections (every threshold: %zu)\n", images0,
	            kittiOrb.detections(), kittiRef.detections);
	EXPECT_LT(kittiOrb.detections(), kittiRef.detections * 6 / 10);
}

TEST(Orb, DistributeOverGridServesEveryCell)
{
	// 400 x 400 image, 4 x 4 cells of 100 px: 1000 strong keypoints crowd the top-left cell, and
	// one weak keypoint sits in each of five other cells.
	std::vector<cv::KeyPoint> kps;
	std::mt19937 rng(9);
	std::uniform_real_distribution<float> c(0, 99), resp(10, 100);
	for (int i = 0; i < 1000; i++)
		kps.emplace_back(cv::Point2f(c(rng), c(rng)), 7.f, -1, resp(rng));
	const std::vector<cv::Point2f> lone = {{150, 50}, {350, 350}, {50, 399}, {399, 0}, {250, 250}};
	for (const auto& pt : lone)
		kps.emplace_back(pt, 7.f, -1, 1.0f);
	const auto out = features::distributeOverGrid(kps, 400, 400, 4, 4, 64);
	ASSERT_EQ(out.size(), 64u);
	for (const auto& pt : lone)
		EXPECT_EQ(std::count_if(out.begin(), out.end(),
		                        [&](const cv::KeyPoint& k) { return k.pt == pt; }),
		          1)
		    << pt;
	// The corner gets its share and the places left over, strongest first.
	std::vector<float> cornerResp;
	for (const auto& k : kps)
		if (k.response > 1.0f)
			cornerResp.push_back(k.response);
	std::sort(cornerResp.rbegin(), cornerResp.rend());
	float weakestKept = 1e9f;
	for (const auto& k : out)
		if (k.response > 1.0f)
			weakestKept = std::min(weakestKept, k.response);
	EXPECT_EQ(weakestKept, cornerResp[64 - lone.size() - 1]);
	// No more than n asked: unchanged.
	EXPECT_EQ(features::distributeOverGrid(kps, 400, 400, 4, 4, 5000).size(), kps.size());
}

namespace
{
/** Points on a ground plane (z = 0, 40 x 40 m) and on the walls given as (x0, y0, x1, y1)
 *  segments 4 m high, about every 0.1 m, with 1 cm of noise. */
std::vector<Eigen::Vector3f> scene(const std::vector<Eigen::Vector4f>& walls, uint32_t seed)
{
	std::mt19937 rng(seed);
	std::normal_distribution<float> noise(0.f, 0.01f);
	std::vector<Eigen::Vector3f> pts;
	for (float x = -20; x < 20; x += 0.1f)
		for (float y = -20; y < 20; y += 0.1f)
			pts.emplace_back(x + noise(rng), y + noise(rng), noise(rng));
	for (const auto& w : walls)
	{
		const Eigen::Vector2f a(w[0], w[1]), b(w[2], w[3]);
		const float len = (b - a).norm();
		for (float s = 0; s < len; s += 0.1f)
			for (float z = 0.1f; z < 4; z += 0.1f)
			{
				const Eigen::Vector2f p = a + (b - a) * (s / len);
				pts.emplace_back(p.x() + noise(rng), p.y() + noise(rng), z + noise(rng));
			}
	}
	return pts;
}
std::vector<Eigen::Vector3f> moved(const std::vector<Eigen::Vector3f>& pts,
                                   const Eigen::Isometry3d& T)
{
	std::vector<Eigen::Vector3f> out;
	for (const auto& p : pts)
		out.push_back((T * p.cast<double>()).cast<float>());
	return out;
}
}  // namespace

TEST(Icp, RecoversAMotionAndReportsWhatGeometryLeavesFree)
{
	// The source is the scene seen from a pose 0.5 m, 0.3 m and 3 deg away from the target's;
	// ICP starts from identity.
	Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
	T.translation() = Eigen::Vector3d(0.5, 0.3, 0.0);
	T.linear() = Eigen::AngleAxisd(3 * kDeg, Eigen::Vector3d::UnitZ()).toRotationMatrix();
	const Eigen::Isometry3d Tinv = T.inverse();
	// A yard: walls on three sides pin every direction.
	{
		const auto target =
		    scene({{-15, -15, 15, -15}, {15, -15, 15, 15}, {-15, 15, 15, 15}, {-5, -3, -5, 3}}, 1);
		const auto r =
		    features::icpPointToPlane(moved(target, Tinv), target, Eigen::Isometry3d::Identity());
		ASSERT_TRUE(r.converged);
		EXPECT_LT((r.T.translation() - T.translation()).norm(), 0.01)
		    << r.T.translation().transpose();
		EXPECT_LT(Eigen::AngleAxisd(r.T.linear().transpose() * T.linear()).angle() / kDeg, 0.05);
		EXPECT_GT(r.overlap, 0.9);
		EXPECT_GT(r.constraint, 0.02);
	}
	// A corridor along x: nothing pins x. The across and up directions are still found, the
	// constraint says the rest is free.
	{
		const auto target = scene({{-20, -4, 20, -4}, {-20, 4, 20, 4}}, 2);
		Eigen::Isometry3d Tc = Eigen::Isometry3d::Identity();
		Tc.translation() = Eigen::Vector3d(0.5, 0.3, 0.1);
		const auto r = features::icpPointToPlane(moved(target, Tc.inverse()), target,
		                                         Eigen::Isometry3d::Identity());
		EXPECT_NEAR(r.T.translation().y(), 0.3, 0.01);
		EXPECT_NEAR(r.T.translation().z(), 0.1, 0.01);
		EXPECT_LT(r.constraint, 0.005);
	}
	// Flat ground only: x, y and yaw are free.
	{
		const auto target = scene({}, 3);
		const auto r =
		    features::icpPointToPlane(moved(target, Tinv), target, Eigen::Isometry3d::Identity());
		EXPECT_LT(r.constraint, 1e-3);
	}
}

TEST(Icp, APreparedTargetAlignsAsAFreshOneWhateverWentBefore)
{
	// A target fits a point's normal the first time an alignment reaches it. Aligning a
	// source on a target that earlier alignments (a part of the scene, another pose) have
	// used must give what the same source gives on a new target, to the last bit.
	const auto target =
	    scene({{-15, -15, 15, -15}, {15, -15, 15, 15}, {-15, 15, 15, 15}, {-5, -3, -5, 3}}, 4);
	Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
	T.translation() = Eigen::Vector3d(0.4, -0.2, 0.05);
	T.linear() = Eigen::AngleAxisd(2 * kDeg, Eigen::Vector3d::UnitZ()).toRotationMatrix();
	const auto source = moved(target, T.inverse());
	// The earlier alignment sees only the points on one side of the yard.
	std::vector<Eigen::Vector3f> part;
	for (const auto& p : source)
		if (p.x() > 5)
			part.push_back(p);
	ASSERT_GT(part.size(), 50u);
	ASSERT_LT(part.size(), source.size() / 2);

	const features::IcpParams prm;
	const features::IcpTarget used(target, prm);
	const auto first = features::icpPointToPlane(part, used, Eigen::Isometry3d::Identity(), prm);
	ASSERT_TRUE(first.converged);
	const auto again = features::icpPointToPlane(source, used, Eigen::Isometry3d::Identity(), prm);
	const auto fresh = features::icpPointToPlane(source, features::IcpTarget(target, prm),
	                                             Eigen::Isometry3d::Identity(), prm);
	ASSERT_TRUE(fresh.converged);
	EXPECT_EQ(again.iterations, fresh.iterations);
	EXPECT_EQ(again.matched, fresh.matched);
	EXPECT_TRUE(again.T.matrix() == fresh.T.matrix()) << again.T.matrix() << "\n"
	                                                  << fresh.T.matrix();
	EXPECT_TRUE(again.H == fresh.H);
	// And the alignment is right (the normals it used are those of the scene).
	EXPECT_LT((fresh.T.translation() - T.translation()).norm(), 0.01);
	// Assessing a pose on the used target agrees with a fresh one as well.
	const auto a = features::assessAlignment(source, used, fresh.T, prm);
	const auto b =
	    features::assessAlignment(source, features::IcpTarget(target, prm), fresh.T, prm);
	EXPECT_EQ(a.matched, b.matched);
	EXPECT_TRUE(a.H == b.H);
	EXPECT_GT(a.overlap, 0.9);
}

TEST(Icp, TheTargetCacheMakesATargetAgainOnlyForOtherPoints)
{
	const auto yard =
	    scene({{-15, -15, 15, -15}, {15, -15, 15, 15}, {-15, 15, 15, 15}, {-5, -3, -5, 3}}, 4);
	Eigen::Isometry3d shift = Eigen::Isometry3d::Identity();
	shift.translation() = Eigen::Vector3d(0.5, 0, 0);
	const auto shifted = moved(yard, shift);
	const features::IcpParams prm;
	features::IcpTargetCache cache(2, prm);
	std::size_t calls = 0;
	const auto of = [&calls](const std::vector<Eigen::Vector3f>& pts)
	{
		return [&calls, &pts]
		{
			++calls;
			return pts;
		};
	};
	const auto a = cache.get(7, 100, of(yard));
	EXPECT_EQ(cache.get(7, 100, of(yard)), a);  // the same key and points: the same target
	EXPECT_EQ(calls, 1u);
	// The same key with other points (a local map grown, or another map's under the same id)
	// is another target, and aligning on it sees those points.
	const auto b = cache.get(7, 101, of(shifted));
	EXPECT_NE(b, a);
	EXPECT_EQ(calls, 2u);
	const auto onB = features::icpPointToPlane(yard, *b, Eigen::Isometry3d::Identity(), prm);
	ASSERT_TRUE(onB.converged);
	EXPECT_LT((onB.T.translation() - shift.translation()).norm(), 0.01)
	    << onB.T.translation().transpose();
	// Two kept: after a is used again, a third drops the least recently used, b.
	EXPECT_EQ(cache.get(7, 100, of(yard)), a);  // now a is the most recent
	EXPECT_EQ(calls, 2u);
	cache.get(8, 100, of(yard));
	EXPECT_EQ(calls, 3u);
	EXPECT_EQ(cache.size(), 2u);
	cache.get(7, 100, of(yard));  // still kept
	EXPECT_EQ(calls, 3u);
	cache.get(7, 101, of(shifted));  // dropped, made again
	EXPECT_EQ(calls, 4u);
	EXPECT_EQ(cache.made(), 4u);
	EXPECT_EQ(cache.size(), 2u);
}

TEST(Icp, VoxelDownsampleKeepsOnePointAVoxel)
{
	const std::vector<Eigen::Vector3f> pts = {{0.05f, 0.05f, 0.05f}, {0.15f, 0.05f, 0.05f},
	                                          {0.06f, 0.04f, 0.05f}, {-0.05f, 0.05f, 0.05f},
	                                          {1e30f, 0, 0},         {NAN, 0, 0}};
	const auto v = features::voxelDownsample(pts, 0.1);
	ASSERT_EQ(v.size(), 3u);  // three voxels; the far and the NaN points are dropped
	bool sawMean = false;
	for (const auto& p : v)
		sawMean = sawMean || (p - Eigen::Vector3f(0.055f, 0.045f, 0.05f)).norm() < 1e-6f;
	EXPECT_TRUE(sawMean);
}

TEST(Icp, VoxelDownsampleOfAScanKeepsItsRange)
{
	// Four points of a scan: two in one voxel near the sensor, one farther in range, one out.
	std::vector<PointXYZI> scan(4);
	scan[0].x = 1.02f;
	scan[1].x = 1.08f;
	scan[2].y = -9.95f;  // 9.95 m: inside a 10 m range
	scan[3].z = 10.05f;  // 10.05 m: outside
	const auto v = features::voxelDownsample(scan, 0.1, 10.0);
	ASSERT_EQ(v.size(), 2u);
	bool near = false, far = false;
	for (const auto& p : v)
	{
		near = near || (p - Eigen::Vector3f(1.05f, 0, 0)).norm() < 1e-5f;
		far = far || (p - Eigen::Vector3f(0, -9.95f, 0)).norm() < 1e-5f;
	}
	EXPECT_TRUE(near);
	EXPECT_TRUE(far);
}

// planarSearch: the top view of a scene's upright structure, correlated over every yaw step and
// shift, finds where a source lies in a target with no prior, and nothing without structure.
TEST(PlanarSearch, FindsAFarTurnedPoseWithNoPriorAndNothingOnBareGround)
{
	// A yard of walls, the source seen from 11 m, -6 m and 137 degrees away: the best
	// hypothesis is that pose within half a cell (0.5 m) and a yaw step (2 degrees).
	const auto target = scene(
	    {{-15, -15, 15, -15}, {15, -15, 15, 5}, {-8, 15, 15, 15}, {-5, -3, -5, 6}, {4, 2, 9, 2}},
	    7);
	const Eigen::Isometry3d T = motion(137, Eigen::Vector3d(11, -6, 0));
	const auto hyps = features::planarSearch(moved(target, T.inverse()), target);
	ASSERT_FALSE(hyps.empty());
	EXPECT_LE(hyps.size(), 8u);
	const auto& best = hyps.front();
	EXPECT_LT((best.T.translation() - T.translation()).norm(), 0.5)
	    << best.T.translation().transpose();
	EXPECT_LT(Eigen::AngleAxisd(best.T.linear().transpose() * T.linear()).angle() / kDeg, 2.0);
	EXPECT_GT(best.score, 0.8);
	for (std::size_t i = 1; i < hyps.size(); i++)
	{
		EXPECT_LE(hyps[i].score, hyps[i - 1].score);  // best first
		// and distinct: 3 m (exactly 3 cells is distinct) or 10 degrees from the best
		const Eigen::Isometry3d d = best.T.inverse() * hyps[i].T;
		EXPECT_TRUE(d.translation().norm() >= 3.0 - 1e-6 ||
		            Eigen::AngleAxisd(d.linear()).angle() / kDeg >= 10.0)
		    << i << ": " << d.translation().norm() << " m, "
		    << Eigen::AngleAxisd(d.linear()).angle() / kDeg << " deg";
	}
	// Flat ground alone has no structure cell: no hypothesis rather than a guess.
	EXPECT_TRUE(features::planarSearch(scene({}, 8), target).empty());

	// A real KITTI scan against itself moved 23 m and turned by -71 degrees: its walls, trees
	// and cars give the pose back, among 180 yaw steps, to the 1 m grid of the hypotheses
	// (half a cell on each axis: 9.5 m lies between two of them).
	RASTERSLAM_REQUIRE_SHARED_DATA();
	const auto pts = io::loadKittiBin(test::sharedData("kitti00-0000-0100/velodyne/000040.bin"));
	std::vector<Eigen::Vector3f> real;
	for (const auto& p : pts)
		real.emplace_back(p.x, p.y, p.z);
	const Eigen::Isometry3d Tr = motion(-71, Eigen::Vector3d(-21, 9.5, 0));
	features::PlanarSearchParams params;
	params.range_m = 40;
	const auto r = features::planarSearch(moved(real, Tr.inverse()), real, params);
	ASSERT_FALSE(r.empty());
	EXPECT_LT((r.front().T.translation() - Tr.translation()).norm(), 0.75)
	    << r.front().T.translation().transpose();
	EXPECT_LT(Eigen::AngleAxisd(r.front().T.linear().transpose() * Tr.linear()).angle() / kDeg,
	          2.0);
}

// freeSpaceConflicts: an alignment that puts one cloud's walls and poles where the other saw
// bare ground is contradicted; the right one is not, and neither is what one side could not see.
TEST(FreeSpace, WallsOnTheOtherSidesBareGroundContradictAnAlignment)
{
	// A street between two walls, 8 m apart, with two poles.
	const auto pole = [](float x, float y)
	{
		std::vector<Eigen::Vector3f> p;
		for (float z = 0.1f; z < 5; z += 0.1f)
			p.emplace_back(x, y, z);
		return p;
	};
	auto street = scene({{-19, -4, 19, -4}, {-19, 4, 19, 4}}, 3);
	for (const auto& [x, y] : {std::pair{-6.f, 2.5f}, std::pair{9.f, -2.5f}})
	{
		const auto p = pole(x, y);
		street.insert(street.end(), p.begin(), p.end());
	}
	// The same street seen from 5 m along it and turned by 20 degrees, its own noise.
	const Eigen::Isometry3d T = motion(20, Eigen::Vector3d(5, 0, 0));
	auto again = moved(scene({{-19, -4, 19, -4}, {-19, 4, 19, 4}}, 11), T.inverse());
	for (const auto& [x, y] : {std::pair{-6.f, 2.5f}, std::pair{9.f, -2.5f}})
	{
		const auto p = moved(pole(x, y), T.inverse());
		again.insert(again.end(), p.begin(), p.end());
	}
	// Right: nothing contradicts (the walls' and poles' cells hold structure on both sides).
	const auto right = features::freeSpaceConflicts(again, street, T);
	EXPECT_GT(right.compared, 100u);  // the walls' cells, both ways
	EXPECT_EQ(right.conflicts, 0u);
	// 0.6 m off across the street still right: the pole at y = -2.5 moves into the next cell,
	// which is not bare, its neighbour holding the other side's pole.
	EXPECT_EQ(features::freeSpaceConflicts(again, street, motion(0, {0, 0.6, 0}) * T).conflicts,
	          0u);
	// Wrong: shifted 3 m across the street, one wall stands on the road and the poles move
	// to where the other side saw ground.
	const auto across = features::freeSpaceConflicts(again, street, motion(0, {0, 3, 0}) * T);
	EXPECT_GT(across.share(), 0.3) << across.conflicts << " of " << across.compared;
	// Turned by 90 degrees: the walls cross the road.
	const auto turned = features::freeSpaceConflicts(again, street, motion(90, {0, 0, 0}) * T);
	EXPECT_GT(turned.share(), 0.3) << turned.conflicts << " of " << turned.compared;
	// A pole that only one side has where the other saw bare ground: one pole's cell, both
	// ways as compared by the other's.
	auto moreOnStreet = street;
	const auto extra = pole(0, 0);
	moreOnStreet.insert(moreOnStreet.end(), extra.begin(), extra.end());
	const auto one = features::freeSpaceConflicts(again, moreOnStreet, T);
	EXPECT_EQ(one.conflicts, 1u);
	// With minTop_m, only what also rises higher conflicts: a car-high box (1.5 m) on the
	// street does not, the pole (5 m) still does.
	auto parkedCar = street;
	for (float x = -2; x < 2; x += 0.1f)
		for (float z = 0.1f; z < 1.5f; z += 0.1f)
			parkedCar.emplace_back(x, 0.5f, z);
	features::FreeSpaceParams tall;
	tall.minTop_m = 2.5;
	EXPECT_GE(features::freeSpaceConflicts(again, parkedCar, T).conflicts, 4u);
	EXPECT_EQ(features::freeSpaceConflicts(again, parkedCar, T, tall).conflicts, 0u);
	EXPECT_EQ(features::freeSpaceConflicts(again, moreOnStreet, T, tall).conflicts, 1u);
	EXPECT_GT(features::freeSpaceConflicts(again, street, motion(0, {0, 3, 0}) * T, tall).share(),
	          0.3);
	// What one side did not observe is not free space: the pole beyond the other's ground
	// (x = 30 m, outside its 40 x 40 m patch) conflicts with nothing.
	auto beyond = street;
	const auto far = pole(30, 0);
	beyond.insert(beyond.end(), far.begin(), far.end());
	EXPECT_EQ(features::freeSpaceConflicts(again, beyond, T).conflicts, 0u);
	// Structure above the band (a canopy 4 m up with nothing below) is not low structure.
	auto canopy = street;
	for (float x = -1; x < 1; x += 0.1f)
		for (float y = -1; y < 1; y += 0.1f)
			canopy.emplace_back(x, y, 4.f);
	EXPECT_EQ(features::freeSpaceConflicts(again, canopy, T).conflicts, 0u);
	// Points no cell holds (not finite, or beyond 2^22 cells) are left out, not packed into
	// another cell's key; a cell that is not positive is refused.
	auto strange = again;
	strange.emplace_back(1e30f, 0.f, 1.f);
	strange.emplace_back(0.f, -1e30f, 1.f);
	strange.emplace_back(std::nanf(""), 0.f, 1.f);
	strange.emplace_back(0.f, 0.f, std::numeric_limits<float>::infinity());
	const auto same = features::freeSpaceConflicts(strange, street, T);
	EXPECT_EQ(same.compared, right.compared);
	EXPECT_EQ(same.conflicts, right.conflicts);
	features::FreeSpaceParams noCell;
	noCell.cell_m = 0;
	EXPECT_THROW(features::freeSpaceConflicts(again, street, T, noCell), std::invalid_argument);
	// Nothing to compare: no share.
	EXPECT_EQ(features::freeSpaceConflicts({}, street, T).compared, 0u);
	EXPECT_EQ(features::freeSpaceConflicts({}, street, T).share(), 0.0);
}
