// Local bundle adjustment on a simulated local map: five keyframes along an 8 m path observe
// random landmarks with noisy 3D points and noisy descriptors; BA must associate them into
// tracks, recover the poses from perturbed ones, with and without gross outliers.
#include <gtest/gtest.h>
#include <rasterslam/mapping/local_ba.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <numeric>
#include <random>
#include <stdexcept>

namespace
{
using namespace rasterslam::mapping;
constexpr double kDeg = 3.14159265358979323846 / 180.0;
constexpr int kFrames = 5;
constexpr int kLandmarks = 1500;

Eigen::Isometry3d makePose(double yawDeg, double pitchDeg, const Eigen::Vector3d& t)
{
	Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
	T.linear() = (Eigen::AngleAxisd(yawDeg * kDeg, Eigen::Vector3d::UnitZ()) *
	              Eigen::AngleAxisd(pitchDeg * kDeg, Eigen::Vector3d::UnitY()))
	                 .toRotationMatrix();
	T.translation() = t;
	return T;
}

Eigen::Vector3d randomUnit(std::mt19937& rng)
{
	std::normal_distribution<double> g(0, 1);
	return Eigen::Vector3d(g(rng), g(rng), g(rng)).normalized();
}

/** The anchor (frame 0's true pose) is the world frame. Every feature remembers its landmark. */
struct Scene
{
	std::vector<Eigen::Vector3d> landmarks;
	std::vector<uint32_t> seenBy;                   //!< per landmark, bit k: observed by frame k
	std::vector<Eigen::Isometry3d> truth, initial;  //!< T_anchor_frame
	std::vector<std::vector<uint8_t>> descriptors;
	std::vector<std::vector<float>> xyz;
	std::vector<std::vector<int>> landmarkOf;

	std::vector<BaFrame> frames() const
	{
		std::vector<BaFrame> out(truth.size());
		for (std::size_t k = 0; k < out.size(); k++)
		{
			out[k].descriptors = descriptors[k].data();
			out[k].xyz = xyz[k].data();
			out[k].n = landmarkOf[k].size();
			out[k].T_anchor_frame = initial[k];
		}
		return out;
	}
	std::size_t seenTwice() const
	{
		return std::count_if(seenBy.begin(), seenBy.end(),
		                     [](uint32_t m) { return __builtin_popcount(m) >= 2; });
	}
};

/** ~1500 landmarks in a 60 x 60 x 6 m box; each frame sees a random 60-80 % of those within
 *  30 m, with N(0, 0.03 m) noise and 0-6 flipped descriptor bits; a fraction `outliers` of the
 *  observations is moved 2-5 m. Initial poses: truth moved 0.2-0.3 m and turned 1-2 deg. */
Scene makeScene(uint32_t seed, double outliers = 0, int nLandmarks = kLandmarks)
{
	Scene s;
	std::mt19937 rng(seed);
	std::uniform_real_distribution<double> u(0, 1);
	std::normal_distribution<double> noise(0, 0.03);
	std::vector<std::array<uint8_t, 32>> landmarkDesc(nLandmarks);
	for (int l = 0; l < nLandmarks; l++)
	{
		s.landmarks.emplace_back(-26 + 60 * u(rng), -30 + 60 * u(rng), -3 + 6 * u(rng));
		for (auto& b : landmarkDesc[l])
			b = static_cast<uint8_t>(rng() & 0xff);
	}
	s.seenBy.assign(nLandmarks, 0);
	for (int k = 0; k < kFrames; k++)
		s.truth.push_back(
		    k == 0 ? Eigen::Isometry3d::Identity()
		           : makePose(3.0 * k, k % 2 ? 0.8 : -0.5, {2.0 * k, 0.4 * std::sin(k), 0.05 * k}));
	s.descriptors.resize(kFrames);
	s.xyz.resize(kFrames);
	s.landmarkOf.resize(kFrames);
	for (int k = 0; k < kFrames; k++)
	{
		const double fraction = 0.6 + 0.2 * u(rng);
		std::vector<int> seen;
		for (int l = 0; l < nLandmarks; l++)
			if ((s.landmarks[l] - s.truth[k].translation()).norm() < 30 && u(rng) < fraction)
				seen.push_back(l);
		// Feature order unrelated to landmark order, as in a real image.
		std::shuffle(seen.begin(), seen.end(), rng);
		for (int l : seen)
		{
			s.seenBy[l] |= 1u << k;
			Eigen::Vector3d z = s.truth[k].inverse() * s.landmarks[l];
			z += Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
			if (u(rng) < outliers)
				z += (2 + 3 * u(rng)) * randomUnit(rng);
			for (int c = 0; c < 3; c++)
				s.xyz[k].push_back(static_cast<float>(z[c]));
			auto d = landmarkDesc[l];
			std::vector<int> bits(256);
			std::iota(bits.begin(), bits.end(), 0);
			std::shuffle(bits.begin(), bits.end(), rng);
			const int flips = static_cast<int>(rng() % 7);
			for (int b = 0; b < flips; b++)
				d[bits[b] / 8] ^= static_cast<uint8_t>(1u << (bits[b] % 8));
			s.descriptors[k].insert(s.descriptors[k].end(), d.begin(), d.end());
			s.landmarkOf[k].push_back(l);
		}
	}
	for (int k = 0; k < kFrames; k++)
	{
		if (k == 0)
		{
			s.initial.push_back(s.truth[0]);
			continue;
		}
		Eigen::Isometry3d T = s.truth[k];
		T.translation() += (0.2 + 0.1 * u(rng)) * randomUnit(rng);
		T.linear() =
		    T.linear() * Eigen::AngleAxisd((1 + u(rng)) * kDeg, randomUnit(rng)).toRotationMatrix();
		s.initial.push_back(T);
	}
	return s;
}

struct PoseError
{
	double translation_m = 0, rotation_deg = 0;  //!< means over all pairs of frames
};
/** Error of the relative pose between every pair of frames. */
PoseError relativePoseError(const std::vector<Eigen::Isometry3d>& est,
                            const std::vector<Eigen::Isometry3d>& truth)
{
	PoseError e;
	int n = 0;
	for (std::size_t i = 0; i < est.size(); i++)
		for (std::size_t j = i + 1; j < est.size(); j++)
		{
			const Eigen::Isometry3d d =
			    (truth[i].inverse() * truth[j]).inverse() * (est[i].inverse() * est[j]);
			e.translation_m += d.translation().norm();
			e.rotation_deg += Eigen::AngleAxisd(d.linear()).angle() / kDeg;
			n++;
		}
	e.translation_m /= n;
	e.rotation_deg /= n;
	return e;
}

bool samePose(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b)
{
	return std::memcmp(a.matrix().data(), b.matrix().data(), sizeof(double) * 16) == 0;
}

TEST(LocalBa, RecoversPosesAndMergesTracks)
{
	const Scene s = makeScene(7);
	const auto frames = s.frames();
	LocalBaParams params;
	// Two initial poses each 1-2 deg off displace a point 30 m away by up to 2 m between them:
	// the default 1 m gate would lose some far matches (measured: 1-7 % of the tracks).
	params.gate_m = 2.5;
	const LocalBaResult r = localBundleAdjustment(frames, params);
	ASSERT_TRUE(r.ran) << r.message;
	ASSERT_EQ(r.T_anchor_frame.size(), frames.size());
	EXPECT_TRUE(samePose(r.T_anchor_frame[0], frames[0].T_anchor_frame));

	const PoseError before = relativePoseError(s.initial, s.truth);
	const PoseError after = relativePoseError(r.T_anchor_frame, s.truth);
	EXPECT_LT(after.translation_m * 3, before.translation_m);
	EXPECT_LT(after.rotation_deg * 3, before.rotation_deg);
	EXPECT_LT(after.translation_m, 0.01);
	EXPECT_LT(after.rotation_deg, 0.03);
	EXPECT_LT(r.finalRms_m, r.initialRms_m);
	EXPECT_LT(r.finalRms_m, 0.06);  // 0.03 m per axis, 3 axes, shared with the point estimate

	const double seenTwice = static_cast<double>(s.seenTwice());
	EXPECT_NEAR(static_cast<double>(r.tracks), seenTwice, 0.03 * seenTwice);
	EXPECT_GT(r.observations, 2 * r.tracks);
	ASSERT_EQ(r.descriptors.size(), 32 * r.points.size());
	ASSERT_EQ(r.observers.size(), r.points.size());
	ASSERT_EQ(r.pointOfFeature.size(), frames.size());

	// Walk the features: each names its point, whose observers and descriptor must agree.
	std::vector<uint32_t> observersFromFeatures(r.points.size(), 0);
	std::vector<int> landmarkOfPoint(r.points.size(), -1);
	std::vector<char> descriptorChecked(r.points.size(), 0);
	std::size_t wrongMerges = 0, leftOut = 0;
	for (int k = 0; k < kFrames; k++)
		for (std::size_t f = 0; f < frames[k].n; f++)
		{
			const int p = r.pointOfFeature[k][f];
			if (p < 0)
			{
				leftOut++;
				continue;
			}
			ASSERT_LT(p, static_cast<int>(r.points.size()));
			observersFromFeatures[p] |= 1u << k;
			const int l = s.landmarkOf[k][f];
			if (landmarkOfPoint[p] < 0)
			{
				// Frames are walked in order: this is the lowest-index observation.
				landmarkOfPoint[p] = l;
				EXPECT_EQ(std::memcmp(&r.descriptors[32 * p], frames[k].descriptors + 32 * f, 32),
				          0);
				descriptorChecked[p] = 1;
			}
			else if (landmarkOfPoint[p] != l)
				wrongMerges++;
		}
	EXPECT_EQ(wrongMerges, 0u);
	EXPECT_LT(leftOut, 10u);
	std::size_t sameObserversAsTruth = 0, tracked = 0;
	std::vector<double> trackError;
	for (std::size_t p = 0; p < r.points.size(); p++)
	{
		ASSERT_TRUE(descriptorChecked[p]);
		EXPECT_EQ(r.observers[p], observersFromFeatures[p]);
		const int l = landmarkOfPoint[p];
		// Every observer really saw the landmark (no wrong merge).
		EXPECT_EQ(r.observers[p] & ~s.seenBy[l], 0u);
		if (__builtin_popcount(r.observers[p]) < 2)
			continue;
		tracked++;
		sameObserversAsTruth += r.observers[p] == s.seenBy[l];
		trackError.push_back((r.points[p].cast<double>() - s.landmarks[l]).norm());
	}
	EXPECT_EQ(tracked, r.tracks);
	EXPECT_GT(static_cast<double>(sameObserversAsTruth), 0.97 * tracked);
	std::nth_element(trackError.begin(), trackError.begin() + trackError.size() / 2,
	                 trackError.end());
	EXPECT_LT(trackError[trackError.size() / 2], 0.05);
}

TEST(LocalBa, HuberKeepsGrossOutliersFromBendingThePoses)
{
	const Scene s = makeScene(11, 0.10);
	const auto frames = s.frames();
	LocalBaParams p;
	p.gate_m = 0;  // without the gate, the moved observations join their tracks: BA must cope
	const LocalBaResult r = localBundleAdjustment(frames, p);
	ASSERT_TRUE(r.ran) << r.message;
	const PoseError before = relativePoseError(s.initial, s.truth);
	const PoseError after = relativePoseError(r.T_anchor_frame, s.truth);
	EXPECT_LT(after.translation_m * 3, before.translation_m);
	EXPECT_LT(after.rotation_deg * 3, before.rotation_deg);
	EXPECT_LT(after.translation_m, 0.02);

	// Plain least squares over the same tracks is pulled further by the outliers.
	p.huber = 0;
	const LocalBaResult plain = localBundleAdjustment(frames, p);
	ASSERT_TRUE(plain.ran) << plain.message;
	const PoseError afterPlain = relativePoseError(plain.T_anchor_frame, s.truth);
	EXPECT_LT(after.translation_m, afterPlain.translation_m);
}

TEST(LocalBa, NothingToAdjustAndInvalidInput)
{
	const Scene s = makeScene(3);
	std::vector<BaFrame> one = {s.frames()[1]};
	const LocalBaResult r = localBundleAdjustment(one, LocalBaParams{});
	EXPECT_FALSE(r.ran);
	ASSERT_EQ(r.T_anchor_frame.size(), 1u);
	EXPECT_TRUE(samePose(r.T_anchor_frame[0], one[0].T_anchor_frame));
	EXPECT_EQ(r.tracks, 0u);
	EXPECT_EQ(r.observations, 0u);
	ASSERT_EQ(r.points.size(), one[0].n);
	ASSERT_EQ(r.descriptors.size(), 32 * one[0].n);
	// Each feature becomes a point, mapped into the anchor frame with the given pose.
	const Eigen::Vector3f expected =
	    (one[0].T_anchor_frame * Eigen::Vector3f(one[0].xyz).cast<double>()).cast<float>();
	EXPECT_LT((r.points[r.pointOfFeature[0][0]] - expected).norm(), 1e-5f);
	EXPECT_EQ(r.observers[0], 1u);

	std::vector<BaFrame> tooMany(33, s.frames()[0]);
	EXPECT_THROW(localBundleAdjustment(tooMany, LocalBaParams{}), std::invalid_argument);
	std::vector<BaFrame> nullXyz = s.frames();
	nullXyz[2].xyz = nullptr;
	EXPECT_THROW(localBundleAdjustment(nullXyz, LocalBaParams{}), std::invalid_argument);
}

TEST(LocalBa, Deterministic)
{
	const Scene s = makeScene(5);
	const auto frames = s.frames();
	const LocalBaResult a = localBundleAdjustment(frames, LocalBaParams{});
	const LocalBaResult b = localBundleAdjustment(frames, LocalBaParams{});
	ASSERT_TRUE(a.ran);
	ASSERT_EQ(a.T_anchor_frame.size(), b.T_anchor_frame.size());
	for (std::size_t k = 0; k < a.T_anchor_frame.size(); k++)
		EXPECT_TRUE(samePose(a.T_anchor_frame[k], b.T_anchor_frame[k])) << "frame " << k;
	ASSERT_EQ(a.points.size(), b.points.size());
	EXPECT_EQ(std::memcmp(a.points.data(), b.points.data(), sizeof(a.points[0]) * a.points.size()),
	          0);
	EXPECT_EQ(a.iterations, b.iterations);
	EXPECT_EQ(a.finalRms_m, b.finalRms_m);
}

}  // namespace
