// rasterslam-bench-places: how well the bag-of-words database ranks the true place among
// many distractors. Places are scans of several simulated towns (one database entry a place,
// every few metres of each town's route), or with --local-maps local-map images as the map
// manager makes them (the non-ground points of 5 keyframes in the first one's frame, poses
// from the simulator); queries are scans of the same towns from other poses (to the side,
// turned, or driven the other way) with other noise, and with --other-towns scans of towns
// that are not in the database. Reports recall@1 and recall@5 against a random ranking, the
// precision-recall curve of the best place's normalized score, and the query time. With
// --verify, the first candidates of each query are verified image against image (ORB
// matches of the two images' keypoints, the 3D points behind them fitted by RANSAC), timed,
// and a query's accepted place is judged by its registration against the simulator's truth.
#include <mrpt/core/format.h>
#include <mrpt/maps/registerAllClasses.h>
#include <mrpt/obs/registerAllClasses.h>
#include <rasterslam/bow/vocabulary.h>
#include <rasterslam/cli/app.h>
#include <rasterslam/core/pose_conversions.h>
#include <rasterslam/features/matcher.h>
#include <rasterslam/features/orb_extractor.h>
#include <rasterslam/features/rigid_ransac.h>
#include <rasterslam/io/kitti.h>
#include <rasterslam/io/trajectory_io.h>
#include <rasterslam/places/fusion.h>
#include <rasterslam/places/polar_context.h>
#include <rasterslam/places/turned_views.h>
#include <rasterslam/raster/elevation_image.h>
#include <rasterslam/sim/cloud_world.h>
#include <rasterslam/sim/simulator.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <limits>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <optional>
#include <string>
#include <tuple>
#include <vector>

namespace cli = rasterslam::cli;
using namespace rasterslam;

namespace
{
const char* kDescription =
    "rasterslam-bench-places: ranks the true place among many simulated distractor places with "
    "the BOW database (vocabulary tree, TF-IDF, L1 score) and reports recall@1, recall@5, the "
    "precision-recall curve of the best place's normalized score and the query time. A place "
    "is the elevation image of one scan, or with --local-maps a local-map image as the map "
    "manager makes it. With --verify the first candidates are also verified image against "
    "image (matches, RANSAC of the 3D points behind them): the verification's time a candidate, "
    "and the accepted places judged by their registration against the truth. With --kitti the "
    "real street of a KITTI folder joins them: its places are made of the real scans, its "
    "queries rendered from those scans at other poses (rasterslam-sim --kitti's renderer).";

struct Args
{
	std::string scenario, vocabulary;
	int towns = 20;
	long long seed0 = 1000;
	double every_m = 8, offset_m = 3, yaw_deg = 20, truth_m = 8;
	int queriesPerTown = 6;
	bool json = false;
	bool localMaps = false, queryLocalMaps = false;
	int keyframes = 5;
	double keyframeEvery_m = 4;
	int otherTowns = 0;
	bool verify = false;
	int candidates = 5, minInliers = 25;
	std::string kitti;  //!< a KITTI folder: its street joins the database as one more town
	int kittiQueries = 20;
	double poseTruth_m = 1.0, poseTruth_deg = 3.0;
};

/** What a place or a query keeps: its words, the score of its halves (the normalizer), and
 *  with --verify its descriptors and the 3D point behind each (in the image's frame). */
struct Described
{
	bow::BowVector words;
	double selfScore = 0;
	cv::Mat desc;
	std::vector<Eigen::Vector3f> pts;
	/** --direct-index: each feature's vocabulary node (a DBoW2 direct index). */
	std::vector<uint32_t> groups;
	std::size_t nGroups = 0;     //!< distinct nodes among `groups`
	mrpt::poses::CPose3D frame;  //!< of the image, in the simulated world
	/** --query-turns: the words and normalizer of the same points rasterized turned by
	 *  k * 90 / N degrees, k = 1..N-1 (queries only). */
	std::vector<places::TurnedView> turns;
	/** --polar: the polar context of the image's points (ground removed); a local-map
	 *  place's about each of its keyframes, a query's about its middle keyframe. */
	std::vector<places::PolarContext> polar;
};

struct Place
{
	int town = 0;
	std::vector<Eigen::Vector3d> positions;  //!< of its scan, or of its local map's keyframes
	double distanceTo(const Eigen::Vector3d& p) const
	{
		double d = std::numeric_limits<double>::infinity();
		for (const auto& q : positions)
			d = std::min(d, (q - p).head<2>().norm());
		return d;
	}
};

bool gCanonical = false;
int gQueryTurns = 1;       //!< --query-turns
double gTurnWeight = 0.8;  //!< --turn-weight

bool gVerify = false;
int gDirectLevels = 0;             //!< --direct-index
bool gPolar = false;               //!< --polar
int gFuseK = 10;                   //!< --polar: the constant of the reciprocal-rank fusion
places::PolarParams gPolarParams;  //!< --polar-rings, --polar-sectors, --polar-range
places::PolarParams polarParams()
{
	places::PolarParams pp = gPolarParams;
	pp.heightOffset_m = raster::RasterParams().sensorHeight_m;
	return pp;
}

double gMaxHeight = 0;    //!< --max-height: the scans' band above the ground (0: all)
std::string gSaveImages;  //!< --save-images: folder of the places' images
std::size_t gImagesSaved = 0;

/** --save-images: a place's image as DIR/NNNNNN.png (to train a vocabulary on). */
void saveImage(const RasterFrame& f)
{
	if (gSaveImages.empty())
		return;
	const std::string path = gSaveImages + "/" + mrpt::format("%06zu.png", gImagesSaved++);
	std::vector<uchar> png;
	if (!cv::imencode(".png", f.image.asCvMatRef(), png))
		throw std::runtime_error(path + ": cannot encode the image as PNG");
	// A temporary name and a rename: an interrupted run leaves no half-written image behind.
	io::writeFileAtomically(path, std::string(png.begin(), png.end()));
}

/** The words of an image whose pixels index `pts`; with --verify also the features that have
 *  a point behind them (the loop detector's keyframes keep the same). */
Described describe(const RasterFrame& f, const std::vector<PointXYZI>& pts,
                   const bow::Vocabulary& vocab, features::OrbExtractor& orb,
                   const mrpt::poses::CPose3D& frame)
{
	std::vector<cv::KeyPoint> kps;
	cv::Mat desc;
	orb.extract(f.image.asCvMatRef(), kps, desc);
	const auto d = bow::toDescriptors(desc.ptr<uint8_t>(), desc.empty() ? 0 : desc.rows);
	Described out;
	vocab.transform(d, out.words);
	out.selfScore = vocab.selfScore(d);
	out.frame = frame;
	if (gVerify)
	{
		out.desc.create(0, 32, CV_8U);
		for (std::size_t i = 0; i < kps.size(); i++)
		{
			const int32_t idx = raster::pointAtPixel(f, kps[i].pt.x, kps[i].pt.y);
			if (idx < 0)
				continue;
			const auto& q = pts[static_cast<std::size_t>(idx)];
			out.pts.emplace_back(q.x, q.y, q.z);
			out.desc.push_back(desc.row(static_cast<int>(i)));
		}
		if (gDirectLevels > 0 && !out.desc.empty())
		{
			// Stored with the image, as a database keeps its direct index.
			bow::BowVector unused;
			bow::FeatureVector fv;
			vocab.transform(bow::toDescriptors(out.desc.ptr<uint8_t>(), out.desc.rows), unused, &fv,
			                gDirectLevels);
			out.groups.assign(static_cast<std::size_t>(out.desc.rows), 0);
			out.nGroups = fv.size();
			for (const auto& [node, rows] : fv)
				for (const auto r : rows)
					out.groups[r] = node;
		}
	}
	return out;
}

/** How a scan is rasterized: the defaults, or with --max-height lifelong.yaml's band. */
raster::RasterParams scanRasterParams()
{
	raster::RasterParams rp;
	if (gMaxHeight > 0)  // lifelong.yaml's rasterizer sets max_height_m and grey_max_m alike
	{
		rp.maxHeight_m = gMaxHeight;
		rp.greyMax_m = gMaxHeight;
	}
	return rp;
}

RasterFrame rasterOf(const Scan& scan, uint32_t seed, raster::Plane* planeOut = nullptr)
{
	const raster::Plane plane = raster::fitGroundPlane(scan.points, raster::GroundParams(), seed);
	raster::RasterParams rp = scanRasterParams();
	rp.canonicalYaw = gCanonical;
	RasterFrame f;
	raster::rasterizeElevation(scan.points, plane, rp, f);
	if (planeOut)
		*planeOut = plane;
	return f;
}

/** A scan's image described; its normalizer (as the loop detector normalizes a query with
 *  no previous keyframe) is the score of its even features against its odd ones. */
Described scanPlace(const Scan& scan, const mrpt::poses::CPose3D& pose,
                    const bow::Vocabulary& vocab, features::OrbExtractor& orb, uint32_t seed,
                    bool query = false)
{
	raster::Plane plane;
	const RasterFrame f = rasterOf(scan, seed, &plane);
	if (!query)
		saveImage(f);
	auto d = describe(f, scan.points, vocab, orb, pose);
	if (query)
		d.turns = places::turnedViews(scan.points, plane, scanRasterParams(), gQueryTurns, vocab,
		                              orb);  // as the loop detector makes them
	if (gPolar)
	{
		std::vector<PointXYZI> projected;  // the image's points: ground removed, in the band
		raster::appendImagePoints(f, scan.points, projected);
		d.polar.push_back(places::polarContext(projected, polarParams()));
	}
	return d;
}

/** The local-map image of scans at `poses` (the map manager's way): each scan's projected
 *  points (its image's, ground removed) moved into the first scan's frame, rasterized with
 *  the map manager's defaults (0.2 m a pixel, +-60 m, no ground removal). */
Described localMapPlace(const std::vector<Scan>& scans,
                        const std::vector<mrpt::poses::CPose3D>& poses,
                        const bow::Vocabulary& vocab, features::OrbExtractor& orb, uint32_t seed,
                        bool query = false, std::size_t centre = 0)
{
	std::vector<PointXYZI> pts;
	for (std::size_t i = 0; i < scans.size(); i++)
	{
		const RasterFrame f = rasterOf(scans[i], seed + static_cast<uint32_t>(i));
		std::vector<PointXYZI> projected;
		raster::appendImagePoints(f, scans[i].points, projected);
		raster::appendMoved(projected, toIsometry(poses[i] - poses[0]).cast<float>(), pts);
	}
	raster::RasterParams mp = raster::localMapRasterParams();
	mp.canonicalYaw = gCanonical;
	RasterFrame img;
	raster::rasterizeElevation(pts, raster::Plane(), mp, img);
	if (!query)
		saveImage(img);
	auto d = describe(img, pts, vocab, orb, poses[0]);
	if (query)
		d.turns = places::turnedViews(pts, raster::Plane(), raster::localMapRasterParams(),
		                              gQueryTurns, vocab, orb);
	if (gPolar)
	{
		// A query about the keyframe at its position, `centre` (a local map driven the other
		// way starts at the far end), a place about each keyframe (a query is then within
		// half a keyframe step of one of them along the road).
		for (std::size_t k = query ? std::min(centre, poses.size() - 1) : 0; k < poses.size(); k++)
		{
			std::vector<PointXYZI> centred;
			raster::appendMoved(pts, toIsometry(poses[0] - poses[k]).cast<float>(), centred);
			d.polar.push_back(places::polarContext(centred, polarParams()));
			if (query)
				break;
		}
	}
	return d;
}

/** One candidate verified: the query's features matched to the place's, the 3D points of
 *  the matches fitted by RANSAC (the loop detector's defaults: ratio 0.9, 64 bits, 0.4 m,
 *  1,000 iterations); the fit maps the query's frame into the place's. */
struct Verification
{
	features::RigidResult fit;
	std::size_t matches = 0;
	double ms = 0;
};

Verification verifyPair(const Described& q, const Described& p, int minInliers, uint32_t seed)
{
	const auto t0 = std::chrono::steady_clock::now();
	features::MatchParams mp;
	mp.maxDistance = 64;
	mp.ratio = 0.9f;
	const auto matches = !q.groups.empty() && !p.groups.empty()
	                         ? features::matchMutualGrouped(q.desc, p.desc, mp, q.groups, p.groups)
	                         : features::matchMutual(q.desc, p.desc, mp);
	std::vector<Eigen::Vector3f> a, b;
	for (const auto& m : matches)
	{
		a.push_back(q.pts[static_cast<std::size_t>(m.a)]);
		b.push_back(p.pts[static_cast<std::size_t>(m.b)]);
	}
	features::RansacParams rp;
	rp.inlierThreshold_m = 0.4;
	rp.maxIterations = 1000;
	rp.minInliers = minInliers;
	Verification v;
	v.fit = features::ransacRigid(a, b, rp, seed);
	v.matches = matches.size();
	v.ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
	return v;
}

/** Translation (m) and rotation (deg) between a fit and the true query-in-place pose. */
std::pair<double, double> registrationError(const Eigen::Isometry3d& fit, const Described& q,
                                            const Described& p)
{
	const Eigen::Isometry3d truth = toIsometry(q.frame - p.frame);
	const Eigen::Isometry3d e = truth.inverse() * fit;
	return {e.translation().norm(), Eigen::AngleAxisd(e.rotation()).angle() * 180 / M_PI};
}

int run(const Args& a)
{
	const auto vocab = bow::loadVocabularyFile(a.vocabulary);
	features::OrbParams op;
	op.numFeatures = 3000;  // as the loop detector's queries and the map manager's images
	op.levels = 3;
	features::OrbExtractor orb(op);
	bow::Database db;
	std::vector<Place> places;  // by entry id order of insertion
	std::vector<bow::Database::EntryId> ids;
	std::vector<Described> placeImages;            // with --verify, by place (their words dropped)
	places::PolarIndex polarIndex(polarParams());  // --polar: the places' contexts
	std::vector<std::size_t> polarPlace;           // by context: its place
	const auto keep = [&](Described&& d)
	{
		if (gPolar)
			for (auto& c : d.polar)
			{
				polarIndex.add(std::move(c));
				polarPlace.push_back(ids.size());
			}
		ids.push_back(db.add(d.words));
		if (a.verify)
		{
			d.words.clear();
			placeImages.push_back(std::move(d));
		}
	};
	struct Query
	{
		int town;  // -1: a town not in the database
		Eigen::Vector3d position;
		Described img;
		bool opposite;
	};
	std::vector<Query> queries;
	const auto t0 = std::chrono::steady_clock::now();
	std::size_t scansSimulated = 0;
	for (int t = 0; t < a.towns + a.otherTowns; t++)
	{
		const bool other = t >= a.towns;  // queries only: its places are not in the database
		sim::Scenario sc = sim::loadScenario(a.scenario);
		sc.seed = static_cast<uint32_t>(a.seed0 + t);
		sc.threads = 2;
		const sim::Simulator s = sim::Simulator::fromScenario(sc);
		// Metres a scan and scans a lap; a vehicle that slows for corners (corner_accel_mps2)
		// takes lapTime() over it, and a scan is then the mean step.
		const bool slows = sc.corner_accel_mps2 > 0;
		const double step =
		    slows ? s.route().length() / (s.lapTime() * sc.rate_hz) : sc.speed_mps / sc.rate_hz;
		const auto lap = static_cast<std::size_t>(s.route().length() / step);
		// A local map: `keyframes` keyframes `keyframeEvery_m` apart, and the next one starts
		// at its last keyframe (as the map manager's consecutive maps share one).
		const auto kfEvery =
		    std::max<std::size_t>(1, static_cast<std::size_t>(a.keyframeEvery_m / step));
		const auto every =
		    a.localMaps ? kfEvery * static_cast<std::size_t>(std::max(1, a.keyframes - 1))
		                : std::max<std::size_t>(1, static_cast<std::size_t>(a.every_m / step));
		for (std::size_t k = 0; !other && k < lap; k += every)
		{
			Place place;
			place.town = t;
			if (a.localMaps)
			{
				std::vector<Scan> scans;
				std::vector<mrpt::poses::CPose3D> poses;
				for (int i = 0; i < a.keyframes; i++)
				{
					const std::size_t kk = (k + static_cast<std::size_t>(i) * kfEvery) % lap;
					poses.push_back(s.sensorPose(kk));
					scans.push_back(s.scanFrom(poses.back(), kk, s.stamp(kk)));
					place.positions.emplace_back(poses.back().x(), poses.back().y(),
					                             poses.back().z());
				}
				scansSimulated += scans.size();
				keep(localMapPlace(scans, poses, *vocab, orb, static_cast<uint32_t>(k + 1)));
			}
			else
			{
				const auto pose = s.sensorPose(k);
				const Scan scan = s.scanFrom(pose, k, s.stamp(k));
				++scansSimulated;
				keep(scanPlace(scan, pose, *vocab, orb, static_cast<uint32_t>(k + 1)));
				place.positions.emplace_back(pose.x(), pose.y(), pose.z());
			}
			places.push_back(std::move(place));
		}
		// Queries half-way between places, spread over the lap: to the side and turned,
		// alternately driven the other way; noise drawn for other scan indices.
		for (int q = 0; q < a.queriesPerTown; q++)
		{
			const std::size_t k = (lap * static_cast<std::size_t>(2 * q + 1)) /
			                          static_cast<std::size_t>(2 * a.queriesPerTown) +
			                      every / 2;
			const double side = (q % 2 ? -1 : 1) * a.offset_m;
			const double yaw = (q % 2 ? 180.0 : a.yaw_deg) * M_PI / 180;
			const mrpt::poses::CPose3D aside(0, side, 0, yaw, 0, 0);
			const auto pose = s.sensorPose(k) + aside;
			Described img;
			if (a.queryLocalMaps)
			{
				// A local map of the query's drive around k, its keyframes in the order of
				// that drive (the other way: from the far end).
				std::vector<Scan> scans;
				std::vector<mrpt::poses::CPose3D> poses;
				for (int i = 0; i < a.keyframes; i++)
				{
					const long step =
					    (q % 2 ? -1L : 1L) * (i - a.keyframes / 2) * static_cast<long>(kfEvery);
					const long n = static_cast<long>(lap);
					const auto kk =
					    static_cast<std::size_t>(((static_cast<long>(k) + step) % n + n) % n);
					poses.push_back(s.sensorPose(kk) + aside);
					scans.push_back(s.scanFrom(poses.back(), 1000000 + kk, s.stamp(kk)));
				}
				scansSimulated += scans.size();
				img = localMapPlace(scans, poses, *vocab, orb, static_cast<uint32_t>(k + 7), true,
				                    static_cast<std::size_t>(a.keyframes / 2));
			}
			else
			{
				const Scan scan = s.scanFrom(pose, 1000000 + k, s.stamp(k));
				++scansSimulated;
				img = scanPlace(scan, pose, *vocab, orb, static_cast<uint32_t>(k + 7), true);
			}
			queries.push_back({other ? -1 : t, Eigen::Vector3d(pose.x(), pose.y(), pose.z()),
			                   std::move(img), q % 2 == 1});
		}
	}
	// --kitti: the real street as one more town. Its places are made of the real scans at
	// their (SemanticKITTI) poses, as a map of the recorded drive would hold them; its queries
	// are rendered from the merged scans at poses the drive never took (aside and turned, or
	// driven the other way), so the truth is exact and the geometry real.
	const int kittiTown = a.towns + a.otherTowns;
	std::size_t kittiPlaces = 0;
	if (!a.kitti.empty())
	{
		const std::string D = a.kitti;
		const auto bins = io::listKittiBins(D + "/velodyne");
		const std::string posesFile = D + "/poses_semantickitti.txt";
		const auto route =
		    io::kittiCameraToVelodyne(io::loadTrajectory(posesFile, io::TrajectoryFormat::Kitti),
		                              io::loadKittiCalibTr(D + "/calib.txt"));
		if (bins.size() < 2)
			throw std::runtime_error(D + "/velodyne: " + std::to_string(bins.size()) +
			                         " scans; a street needs at least 2");
		if (route.size() < bins.size())
			throw std::runtime_error(posesFile + ": " + std::to_string(route.size()) +
			                         " poses for " + std::to_string(bins.size()) + " scans in " +
			                         D + "/velodyne");
		const std::size_t n = bins.size();
		// The scans are read twice (merged, then those the places use) rather than all kept:
		// 101 HDL-64 scans would hold 190 MB.
		const auto readScan = [&](std::size_t i)
		{
			Scan s;
			s.index = i;
			s.points = io::loadKittiBin(bins[i]);
			return s;
		};
		sim::CloudWorld world;
		std::vector<double> along(n, 0);  // metres travelled to each scan
		std::vector<PointXYZI> first;
		for (std::size_t i = 0; i < n; i++)
		{
			auto pts = io::loadKittiBin(bins[i]);
			world.add(pts, route[i].pose);
			if (i == 0)
				first = std::move(pts);
			else
				along[i] = along[i - 1] +
				           (route[i].pose.translation() - route[i - 1].pose.translation()).norm();
		}
		const auto lidar =
		    sim::LidarModel::fromRingOrderedScan("kitti-hdl64", first, 2083, 2.5, 120);
		first = {};
		const auto poseOf = [](const Eigen::Isometry3d& T)
		{ return mrpt::poses::CPose3D(mrpt::math::CMatrixDouble44(T.matrix())); };
		// The scan at (or just past) `m` metres along the route.
		const auto scanAt = [&](double m)
		{
			return static_cast<std::size_t>(std::min<std::ptrdiff_t>(
			    static_cast<std::ptrdiff_t>(n) - 1,
			    std::lower_bound(along.begin(), along.end(), m - 1e-9) - along.begin()));
		};
		const double length = along.back();
		const double kfStep = a.localMaps || a.queryLocalMaps ? a.keyframeEvery_m : a.every_m;
		if (a.localMaps)
		{
			// Keyframes every keyframeEvery_m of the drive; a local map of `keyframes` of them,
			// the next starting at its last one.
			std::vector<std::size_t> kfs;
			for (double m = 0; m <= length; m += a.keyframeEvery_m)
				kfs.push_back(scanAt(m));
			const auto per = static_cast<std::size_t>(std::max(1, a.keyframes - 1));
			for (std::size_t k = 0; k + 1 < kfs.size() || (k == 0 && !kfs.empty()); k += per)
			{
				Place place;
				place.town = kittiTown;
				std::vector<Scan> scans;
				std::vector<mrpt::poses::CPose3D> poses;
				for (std::size_t i = k; i < kfs.size() && i < k + per + 1; i++)
				{
					scans.push_back(readScan(kfs[i]));
					poses.push_back(poseOf(route[kfs[i]].pose));
					place.positions.emplace_back(poses.back().x(), poses.back().y(),
					                             poses.back().z());
				}
				keep(localMapPlace(scans, poses, *vocab, orb, static_cast<uint32_t>(k + 1)));
				places.push_back(std::move(place));
				++kittiPlaces;
			}
		}
		else
			for (double m = 0; m <= length; m += a.every_m)
			{
				const auto i = scanAt(m);
				Place place;
				place.town = kittiTown;
				const auto pose = poseOf(route[i].pose);
				place.positions.emplace_back(pose.x(), pose.y(), pose.z());
				keep(scanPlace(readScan(i), pose, *vocab, orb, static_cast<uint32_t>(i + 1)));
				places.push_back(std::move(place));
				++kittiPlaces;
			}
		// Queries spread over the street, alternately aside and turned and driven the other
		// way, as in the towns; a local-map query's keyframes are rendered along its own
		// drive, kfStep apart, and stop at the street's ends.
		for (int q = 0; q < a.kittiQueries; q++)
		{
			const double m = length * (q + 0.5) / a.kittiQueries;
			const bool opposite = q % 2 == 1;
			const double side = (opposite ? -1 : 1) * a.offset_m;
			const double yaw = (opposite ? 180.0 : a.yaw_deg) * M_PI / 180;
			Eigen::Isometry3d aside = Eigen::Isometry3d::Identity();
			aside.translate(Eigen::Vector3d(0, side, 0));
			aside.rotate(Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()));
			const auto render = [&](std::size_t i)
			{
				Scan s;
				s.index = 2000000 + i;
				s.points = world.render(route[i].pose * aside, lidar);
				return s;
			};
			const auto at = scanAt(m);
			const auto pose = poseOf(route[at].pose * aside);
			Described img;
			if (a.queryLocalMaps)
			{
				std::vector<Scan> scans;
				std::vector<mrpt::poses::CPose3D> poses;
				std::size_t centre = 0;  // the keyframe at the query's position (i = keyframes / 2)
				for (int i = 0; i < a.keyframes; i++)
				{
					const double mm = m + (opposite ? -1 : 1) * (i - a.keyframes / 2) * kfStep;
					if (mm < 0 || mm > length)
						continue;
					if (i == a.keyframes / 2)
						centre = poses.size();
					const auto kk = scanAt(mm);
					scans.push_back(render(kk));
					poses.push_back(poseOf(route[kk].pose * aside));
				}
				scansSimulated += scans.size();
				img = localMapPlace(scans, poses, *vocab, orb, static_cast<uint32_t>(at + 7), true,
				                    centre);
			}
			else
			{
				++scansSimulated;
				img = scanPlace(render(at), pose, *vocab, orb, static_cast<uint32_t>(at + 7), true);
			}
			queries.push_back({kittiTown, Eigen::Vector3d(pose.x(), pose.y(), pose.z()),
			                   std::move(img), opposite});
		}
	}
	const double tBuild =
	    std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();

	std::size_t at1 = 0, at5 = 0, withTruth = 0, opp = 0, oppAt5 = 0, others = 0;
	std::vector<double> ms;
	// --polar: the polar contexts' ranking alone, and fused with the words' ranking.
	struct
	{
		std::size_t at1 = 0, at5 = 0, oppAt5 = 0, fusedAt1 = 0, fusedAt5 = 0, fusedOppAt5 = 0;
		std::vector<double> ms, fusedMs;  //!< the polar query; polar, words and fusion
	} polar;
	// The best place of each query: its normalized score, and whether it is a true place
	// (false for every query of another town).
	std::vector<std::pair<double, bool>> best;
	// --verify: each candidate's time and inliers (those of wrong registrations apart), and
	// the place each query accepts (the verified candidate with the most inliers).
	struct Accepted
	{
		std::size_t inliers;
		bool right;
		double error_m, error_deg;
		std::size_t query, rank, matches;
		std::size_t secondInliers;  //!< the most inliers among the query's other candidates
		bool wrongPlace;            //!< another town, or the query's town farther than --truth
		bool hasTruth;  //!< the query has a true place: a right one counts in the recall
	};
	std::vector<Accepted> accepted;
	std::vector<double> verifyMs;
	// Of the wrong registrations, those of wrong places (another town, or farther than --truth:
	// a farther place that still overlaps and registers right is right) are the bound that
	// matters; a true place registered off is a rough fit, not a wrong place.
	std::size_t wrongInliersMax = 0, wrongPlaceInliersMax = 0, verifiedRight = 0;
	// Wrong places that RANSAC fitted with at least --min-inliers (accepted or not).
	struct WrongFit
	{
		std::size_t query, rank, inliers;
		int town;
		double distance_m, error_m, error_deg;
	};
	std::vector<WrongFit> wrongPlaceFits;
	// --kitti: the street's queries on their own (they are also in the totals).
	struct
	{
		std::size_t with = 0, at1 = 0, at5 = 0, accRight = 0, accWrong = 0;
		std::vector<double> err_m, err_deg;
	} street;
	for (std::size_t qi = 0; qi < queries.size(); qi++)
	{
		const auto& q = queries[qi];
		const auto tq = std::chrono::steady_clock::now();
		const auto nres = static_cast<std::size_t>(std::max(5, a.candidates));
		// --query-turns: the best of the query's turned images (their scores on the scale of
		// the image as driven, so that what follows reads them as one query's, and weighed
		// by --turn-weight: a turned image's spurious words otherwise push out the places of
		// queries that were aligned already).
		std::vector<bow::Database::View> views{{&q.img.words, q.img.selfScore}};
		for (const auto& [w, self] : q.img.turns)
			views.push_back({&w, self, gTurnWeight});
		// With --polar the words' first 50 are fused: queried once, the first nres of them are
		// the words' own ranking.
		auto res = db.queryViews(views, gPolar ? std::max<std::size_t>(nres, 50) : nres);
		const auto wordsMs =
		    std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - tq)
		        .count();
		ms.push_back(wordsMs);
		std::vector<uint64_t> wordsRanked;  // --polar: the words' first 50
		for (std::size_t r = 0; r < res.size() && r < 50; r++)
			wordsRanked.push_back(res[r].entry);
		if (res.size() > nres)
			res.resize(nres);
		const auto placeOf = [&](bow::Database::EntryId e)
		{ return static_cast<std::size_t>(std::find(ids.begin(), ids.end(), e) - ids.begin()); };
		const auto isTrue = [&](bow::Database::EntryId e)
		{
			const auto i = placeOf(e);
			return places[i].town == q.town && places[i].distanceTo(q.position) <= a.truth_m;
		};
		// The candidates verified: the words' ranking, or with --polar the fused one.
		std::vector<bow::Database::EntryId> candidates, polarRanked;
		if (gPolar)
		{
			const auto tq2 = std::chrono::steady_clock::now();
			// Each place once, at its best context.
			std::vector<uint64_t> pres;
			for (const auto& r : places::rankPlaces(
			         polarIndex, {q.img.polar.front()},
			         [&](std::size_t c) -> uint64_t { return ids[polarPlace[c]]; }, 50))
				pres.push_back(r.id);
			polar.ms.push_back(
			    std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - tq2)
			        .count());
			polarRanked.assign(pres.begin(), pres.end());
			// Reciprocal-rank fusion of the two rankings' first 50 (as the loop detector's
			// polar_fusion does).
			for (const auto& f : places::fuseRankings(wordsRanked, pres, gFuseK))
				candidates.push_back(static_cast<bow::Database::EntryId>(f.id));
			// The words' query (once, for both) and the polar ranking and fusion.
			polar.fusedMs.push_back(wordsMs + std::chrono::duration<double, std::milli>(
			                                      std::chrono::steady_clock::now() - tq2)
			                                      .count());
		}
		if (!gPolar)
			for (const auto& r : res)
				candidates.push_back(r.entry);
		bool hasTruth = false;  // a place of the query's town within --truth
		for (const auto& p : places)
			hasTruth = hasTruth || (p.town == q.town && p.distanceTo(q.position) <= a.truth_m);
		if (!res.empty())
			best.emplace_back(q.img.selfScore > 1e-6 ? res.front().score / q.img.selfScore : 0,
			                  q.town >= 0 && isTrue(res.front().entry));
		if (a.verify)
		{
			std::optional<Accepted> acc;
			std::vector<std::size_t> counts;
			for (std::size_t r = 0;
			     r < candidates.size() && r < static_cast<std::size_t>(a.candidates); r++)
			{
				const auto i = placeOf(candidates[r]);
				const auto v = verifyPair(q.img, placeImages[i], a.minInliers,
				                          static_cast<uint32_t>(100 * qi + r + 1));
				verifyMs.push_back(v.ms);
				const auto n = v.fit.inliers.size();
				const auto [em, ed] = n >= 3 ? registrationError(v.fit.T, q.img, placeImages[i])
				                             : std::make_pair(1e9, 180.0);
				const bool right =
				    places[i].town == q.town && em <= a.poseTruth_m && ed <= a.poseTruth_deg;
				if (!right)
					wrongInliersMax = std::max(wrongInliersMax, n);
				if (!right && !isTrue(candidates[r]))
				{
					wrongPlaceInliersMax = std::max(wrongPlaceInliersMax, n);
					if (v.fit.ok)
						wrongPlaceFits.push_back(
						    {qi, r, n, places[i].town, places[i].distanceTo(q.position), em, ed});
				}
				verifiedRight += right;
				counts.push_back(n);
				if (v.fit.ok && (!acc || n > acc->inliers))
				{
					acc.emplace();
					acc->inliers = n;
					acc->right = right;
					acc->error_m = em;
					acc->error_deg = ed;
					acc->query = qi;
					acc->rank = r;
					acc->matches = v.matches;
					acc->secondInliers = 0;
					acc->wrongPlace = !isTrue(candidates[r]);
					acc->hasTruth = hasTruth;
				}
			}
			if (acc)
			{
				for (std::size_t r = 0; r < counts.size(); r++)
					if (r != acc->rank)
						acc->secondInliers = std::max(acc->secondInliers, counts[r]);
				accepted.push_back(*acc);
				if (q.town == kittiTown)
				{
					street.accRight += acc->right && hasTruth;
					street.accWrong += !acc->right;
					if (acc->right)
						street.err_m.push_back(acc->error_m),
						    street.err_deg.push_back(acc->error_deg);
				}
			}
		}
		if (q.town < 0)
		{
			++others;
			continue;
		}
		if (!hasTruth)
			continue;
		withTruth++;
		opp += q.opposite;
		const bool onStreet = q.town == kittiTown;
		street.with += onStreet;
		for (std::size_t r = 0; r < res.size() && r < 5; r++)
			if (isTrue(res[r].entry))
			{
				at1 += r == 0;
				at5++;
				oppAt5 += q.opposite;
				street.at1 += onStreet && r == 0;
				street.at5 += onStreet;
				break;
			}
		if (gPolar)
		{
			const auto count = [&](const std::vector<bow::Database::EntryId>& ranked,
			                       std::size_t& n1, std::size_t& n5, std::size_t& nOpp5)
			{
				for (std::size_t r = 0; r < ranked.size() && r < 5; r++)
					if (isTrue(ranked[r]))
					{
						n1 += r == 0;
						n5++;
						nOpp5 += q.opposite;
						break;
					}
			};
			count(polarRanked, polar.at1, polar.at5, polar.oppAt5);
			count(candidates, polar.fusedAt1, polar.fusedAt5, polar.fusedOppAt5);
		}
	}
	std::sort(ms.begin(), ms.end());
	const double median = ms.empty() ? 0 : ms[ms.size() / 2], worst = ms.empty() ? 0 : ms.back();
	const double r1 = withTruth ? static_cast<double>(at1) / static_cast<double>(withTruth) : 0,
	             r5 = withTruth ? static_cast<double>(at5) / static_cast<double>(withTruth) : 0;
	// A random ranking finds one of the ~2 true places among the top 5 this often.
	double truePerQuery = 0;
	std::size_t ownQueries = 0;
	for (const auto& q : queries)
	{
		if (q.town < 0)
			continue;
		++ownQueries;
		for (const auto& p : places)
			truePerQuery += p.town == q.town && p.distanceTo(q.position) <= a.truth_m;
	}
	truePerQuery /= static_cast<double>(std::max<std::size_t>(1, ownQueries));
	const double random5 = std::min(1.0, 5.0 * truePerQuery / static_cast<double>(places.size()));
	// The precision-recall curve of accepting a query's best place when its normalized score
	// reaches a bound (the loop detector's min_score, before any verification): recall over
	// the queries that have a true place, precision over everything accepted (queries of
	// other towns included).
	struct PrPoint
	{
		double bound, precision, recall;
	};
	std::vector<PrPoint> curve;
	double recallAtPrecision1 = 0;
	{
		auto sorted = best;
		std::sort(sorted.begin(), sorted.end(),
		          [](const auto& x, const auto& y) { return x.first > y.first; });
		std::size_t accepted = 0, right = 0;
		for (std::size_t i = 0; i < sorted.size(); i++)
		{
			++accepted;
			right += sorted[i].second;
			// A bound sits between two different scores.
			if (i + 1 < sorted.size() && sorted[i + 1].first == sorted[i].first)
				continue;
			const double precision = static_cast<double>(right) / static_cast<double>(accepted);
			const double recall =
			    withTruth ? static_cast<double>(right) / static_cast<double>(withTruth) : 0;
			curve.push_back({sorted[i].first, precision, recall});
			if (right == accepted)
				recallAtPrecision1 = recall;
		}
	}
	// --verify: the accepted places, and the recall at precision 1 when a bound on the
	// inliers (at least min_inliers) decides instead. Precision counts every accepted place;
	// recall the right ones of the queries that have a true place, over those queries.
	std::size_t accRight = 0, accRightWithTruth = 0;
	std::vector<double> rightErr_m, rightErr_deg;
	std::size_t rightInliersMin = std::numeric_limits<std::size_t>::max();
	double recallAtPrecision1Inliers = 0;
	std::size_t inlierBound = 0;
	{
		auto sorted = accepted;
		std::sort(sorted.begin(), sorted.end(),
		          [](const auto& x, const auto& y) { return x.inliers > y.inliers; });
		std::size_t n = 0, right = 0, rightWithTruth = 0;
		for (std::size_t i = 0; i < sorted.size(); i++)
		{
			++n;
			right += sorted[i].right;
			rightWithTruth += sorted[i].right && sorted[i].hasTruth;
			if (sorted[i].right)
			{
				rightErr_m.push_back(sorted[i].error_m);
				rightErr_deg.push_back(sorted[i].error_deg);
				rightInliersMin = std::min(rightInliersMin, sorted[i].inliers);
			}
			if (i + 1 < sorted.size() && sorted[i + 1].inliers == sorted[i].inliers)
				continue;
			if (right == n && withTruth)
			{
				recallAtPrecision1Inliers =
				    static_cast<double>(rightWithTruth) / static_cast<double>(withTruth);
				inlierBound = sorted[i].inliers;
			}
		}
		accRight = right;
		accRightWithTruth = rightWithTruth;
	}
	const auto medianOf = [](std::vector<double> v)
	{
		if (v.empty())
			return 0.0;
		std::nth_element(v.begin(), v.begin() + static_cast<long>(v.size() / 2), v.end());
		return v[v.size() / 2];
	};
	std::sort(verifyMs.begin(), verifyMs.end());
	const double vMedian = medianOf(verifyMs),
	             // nearest rank: the smallest time that 95 % of the candidates do not exceed
	    vP95 = verifyMs.empty() ? 0 : verifyMs[(verifyMs.size() * 95 + 99) / 100 - 1],
	             vMax = verifyMs.empty() ? 0 : verifyMs.back();
	const double vRecall =
	    withTruth ? static_cast<double>(accRightWithTruth) / static_cast<double>(withTruth) : 0;
	const double vPrecision =
	    accepted.empty() ? 1.0
	                     : static_cast<double>(accRight) / static_cast<double>(accepted.size());
	if (rightInliersMin == std::numeric_limits<std::size_t>::max())
		rightInliersMin = 0;
	// --polar: its ranking alone and fused with the words'.
	const auto shareOf = [&](std::size_t n)
	{ return withTruth ? static_cast<double>(n) / static_cast<double>(withTruth) : 0.0; };
	const double polarMedian = medianOf(polar.ms), fusedMedian = medianOf(polar.fusedMs),
	             polarWorst =
	                 polar.ms.empty() ? 0.0 : *std::max_element(polar.ms.begin(), polar.ms.end());
	if (a.json)
	{
		nlohmann::ordered_json j;
		j["towns"] = a.towns;
		j["places"] = places.size();
		j["place_kind"] = a.localMaps ? "local_map" : "scan";
		j["query_turns"] = gQueryTurns;
		j["turn_weight"] = gTurnWeight;
		j["max_height_m"] = gMaxHeight;
		j["query_kind"] = a.queryLocalMaps ? "local_map" : "scan";
		j["scans_simulated"] = scansSimulated;
		j["queries"] = withTruth;
		j["other_town_queries"] = others;
		j["recall_at_1"] = r1;
		j["recall_at_5"] = r5;
		j["random_recall_at_5"] = random5;
		j["recall_at_5_same_way"] = withTruth > opp ? static_cast<double>(at5 - oppAt5) /
		                                                  static_cast<double>(withTruth - opp)
		                                            : 0.0;
		j["recall_at_5_other_way"] =
		    opp ? static_cast<double>(oppAt5) / static_cast<double>(opp) : 0.0;
		j["answered_queries"] = best.size();
		j["recall_at_precision_1"] = recallAtPrecision1;
		if (gPolar)
			j["polar"] = {{"rings", gPolarParams.rings},
			              {"sectors", gPolarParams.sectors},
			              {"range_m", gPolarParams.maxRange_m},
			              {"recall_at_1", shareOf(polar.at1)},
			              {"recall_at_5", shareOf(polar.at5)},
			              {"query_ms_median", polarMedian},
			              {"fuse_k", gFuseK},
			              {"fused_recall_at_1", shareOf(polar.fusedAt1)},
			              {"fused_recall_at_5", shareOf(polar.fusedAt5)},
			              {"fused_query_ms_median", fusedMedian}};
		auto& c = j["pr_curve"] = nlohmann::ordered_json::array();
		for (const auto& p : curve)
			c.push_back({{"min_score", p.bound}, {"precision", p.precision}, {"recall", p.recall}});
		j["query_ms_median"] = median;
		j["query_ms_max"] = worst;
		j["build_s"] = tBuild;
		if (!a.kitti.empty())
		{
			auto& k = j["kitti_street"];
			k["places"] = kittiPlaces;
			k["queries"] = street.with;
			k["recall_at_1"] = street.with ? static_cast<double>(street.at1) / street.with : 0.0;
			k["recall_at_5"] = street.with ? static_cast<double>(street.at5) / street.with : 0.0;
			if (a.verify)
			{
				k["verified_recall"] =
				    street.with ? static_cast<double>(street.accRight) / street.with : 0.0;
				k["accepted_wrong"] = street.accWrong;
				k["right_error_m_median"] = medianOf(street.err_m);
				k["right_error_deg_median"] = medianOf(street.err_deg);
			}
		}
		if (a.verify)
		{
			auto& v = j["verification"];
			v["candidates_a_query"] = a.candidates;
			v["min_inliers"] = a.minInliers;
			v["direct_index_levels_up"] = gDirectLevels;
			if (gDirectLevels > 0)
			{
				// How finely the direct index splits a place's features: 1 would compare every
				// pair, as without it.
				std::vector<double> groups;
				for (const auto& d : placeImages)
					if (!d.groups.empty())
						groups.push_back(static_cast<double>(d.nGroups));
				v["direct_index_groups_median"] = medianOf(groups);
			}
			v["verified"] = verifyMs.size();
			v["right_registrations"] = verifiedRight;
			v["ms_median"] = vMedian;
			v["ms_p95"] = vP95;
			v["ms_max"] = vMax;
			v["accepted"] = accepted.size();
			v["accepted_right"] = accRight;
			v["recall"] = vRecall;
			v["precision"] = vPrecision;
			v["wrong_inliers_max"] = wrongInliersMax;
			v["wrong_place_inliers_max"] = wrongPlaceInliersMax;
			v["right_inliers_min"] = rightInliersMin;
			v["recall_at_precision_1"] = recallAtPrecision1Inliers;
			v["inlier_bound_at_precision_1"] = inlierBound;
			v["right_error_m_median"] = medianOf(rightErr_m);
			v["right_error_deg_median"] = medianOf(rightErr_deg);
		}
		std::cout << j.dump() << "\n";
		return 0;
	}
	std::printf(
	    "%d towns, %zu places (%s), %zu queries (%.0f m aside, turned %.0f deg or driven the "
	    "other way), %zu of other towns; %zu scans simulated, built in %.1f s\n"
	    "recall@1 %.3f, recall@5 %.3f (random ranking: %.4f; recall@5 same way %zu of %zu, "
	    "other way %zu of %zu); query %.3f ms median, %.3f ms max\n",
	    a.towns, places.size(),
	    a.localMaps ? (std::to_string(a.keyframes) + " keyframes " +
	                   std::to_string(a.keyframeEvery_m).substr(0, 4) + " m apart each")
	                      .c_str()
	                : ("every " + std::to_string(a.every_m).substr(0, 4) + " m").c_str(),
	    withTruth, a.offset_m, a.yaw_deg, others, scansSimulated, tBuild, r1, r5, random5,
	    at5 - oppAt5, withTruth - opp, oppAt5, opp, median, worst);
	if (gPolar)
		std::printf(
		    "polar contexts: recall@1 %.3f, recall@5 %.3f (same way %zu, other way %zu); query "
		    "%.3f ms median, %.3f ms max\n"
		    "fused with the words (reciprocal rank, K %d): recall@1 %.3f, recall@5 %.3f (same way "
		    "%zu, other way %zu); query %.3f ms median (the words' 50 best, polar, fusion); "
		    "--verify "
		    "verifies these\n",
		    shareOf(polar.at1), shareOf(polar.at5), polar.at5 - polar.oppAt5, polar.oppAt5,
		    polarMedian, polarWorst, gFuseK, shareOf(polar.fusedAt1), shareOf(polar.fusedAt5),
		    polar.fusedAt5 - polar.fusedOppAt5, polar.fusedOppAt5, fusedMedian);
	// The curve, thinned to about 12 rows.
	std::printf(
	    "best place accepted when its normalized score reaches:\n  min_score  precision  recall\n");
	const std::size_t stride = std::max<std::size_t>(1, curve.size() / 12);
	for (std::size_t i = 0; i < curve.size(); i++)
		if (i % stride == 0 || i + 1 == curve.size())
			std::printf("  %9.3f  %9.3f  %6.3f\n", curve[i].bound, curve[i].precision,
			            curve[i].recall);
	std::printf("recall at precision 1: %.3f\n", recallAtPrecision1);
	if (a.verify)
		std::printf(
		    "verified %zu candidates (the first %d of each query, image against image%s): %.2f "
		    "ms median, %.2f ms p95, %.2f ms max a candidate; %zu right registrations\n"
		    "accepted (at least %d inliers, the most): %zu, right %zu (within %.1f m and %.1f "
		    "deg; median error %.3f m, %.2f deg): recall %.3f, precision %.3f\n"
		    "inliers: wrong registrations up to %zu (of wrong places %zu), accepted right ones "
		    "from %zu; with the "
		    "bound at %zu, precision 1 at recall %.3f\n",
		    verifyMs.size(), a.candidates,
		    gDirectLevels > 0 ? (", features matched under the same vocabulary node " +
		                         std::to_string(gDirectLevels) + " levels up")
		                            .c_str()
		                      : "",
		    vMedian, vP95, vMax, verifiedRight, a.minInliers, accepted.size(), accRight,
		    a.poseTruth_m, a.poseTruth_deg, medianOf(rightErr_m), medianOf(rightErr_deg), vRecall,
		    vPrecision, wrongInliersMax, wrongPlaceInliersMax, rightInliersMin, inlierBound,
		    recallAtPrecision1Inliers);
	if (!a.kitti.empty())
	{
		std::printf("KITTI street (%s): %zu places, %zu queries: recall@1 %.3f, recall@5 %.3f",
		            a.kitti.c_str(), kittiPlaces, street.with,
		            street.with ? static_cast<double>(street.at1) / street.with : 0.0,
		            street.with ? static_cast<double>(street.at5) / street.with : 0.0);
		if (a.verify)
			std::printf("; verified recall %.3f, %zu accepted wrong; median error %.3f m, %.2f deg",
			            street.with ? static_cast<double>(street.accRight) / street.with : 0.0,
			            street.accWrong, medianOf(street.err_m), medianOf(street.err_deg));
		std::printf("\n");
	}
	for (const auto& w : wrongPlaceFits)
		std::printf(
		    "  wrong place fitted: query %zu (%s), candidate %zu: %zu inliers; the place is %s; "
		    "registration off by %.2f m, %.1f deg\n",
		    w.query,
		    queries[w.query].town < 0            ? "other town"
		    : queries[w.query].town == kittiTown ? "KITTI street"
		                                         : "own town",
		    w.rank + 1, w.inliers,
		    (w.town == queries[w.query].town
		         ? "of the query's town, " + mrpt::format("%.1f", w.distance_m) +
		               " m from the query"
		         : std::string("of another town"))
		        .c_str(),
		    w.error_m, w.error_deg);
	for (const auto& acc : accepted)
		if (!acc.right)
			std::printf(
			    "  wrong: query %zu (%s, %s), candidate %zu: %zu inliers of %zu matches, the "
			    "next candidate %zu; %s, registration off by %.2f m, %.1f deg\n",
			    acc.query,
			    queries[acc.query].town < 0            ? "other town"
			    : queries[acc.query].town == kittiTown ? "KITTI street"
			                                           : "own town",
			    queries[acc.query].opposite ? "driven the other way" : "aside and turned",
			    acc.rank + 1, acc.inliers, acc.matches, acc.secondInliers,
			    acc.wrongPlace ? "a wrong place" : "a true place", acc.error_m, acc.error_deg);
	return 0;
}
}  // namespace

int main(int argc, char** argv)
{
	Args args;
	CLI::App app(kDescription, "rasterslam-bench-places");
	cli::configure(app);
	app.add_option("--scenario", args.scenario, "scenario of the towns (their seeds vary)")
	    ->required()
	    ->check(CLI::ExistingFile.description(""))
	    ->type_name("FILE");
	app.add_option("--vocabulary", args.vocabulary, "vocabulary file")
	    ->required()
	    ->check(CLI::ExistingFile.description(""))
	    ->type_name("FILE");
	app.add_option("--towns", args.towns, "towns (default 20)")
	    ->check(CLI::Range(1, 100000).description(""))
	    ->type_name("N");
	app.add_option("--seed", args.seed0, "seed of the first town; the others follow (1000)")
	    ->check(CLI::Range(0LL, 0xFFFFFFFFLL).description(""))
	    ->type_name("S");
	app.add_option("--every", args.every_m, "metres between places along a route (8)")
	    ->check(CLI::Range(0.5, 1000.0).description(""))
	    ->type_name("M");
	app.add_option("--queries", args.queriesPerTown, "queries a town (6)")
	    ->check(CLI::Range(1, 1000).description(""))
	    ->type_name("N");
	app.add_option("--offset", args.offset_m, "queries this far to the side (3 m)")
	    ->check(CLI::Range(0.0, 50.0).description(""))
	    ->type_name("M");
	app.add_option("--yaw", args.yaw_deg, "same-way queries turned by this (20 deg)")
	    ->check(CLI::Range(-180.0, 180.0).description(""))
	    ->type_name("DEG");
	app.add_option("--truth", args.truth_m, "a place within this of the query is true (8 m)")
	    ->check(CLI::Range(0.1, 1000.0).description(""))
	    ->type_name("M");
	app.add_flag("--json", args.json, "print one JSON object");
	app.add_flag("--local-maps", args.localMaps,
	             "a place is a local-map image (--keyframes scans --keyframe-every m apart, the "
	             "map manager's way) instead of one scan's image");
	app.add_flag("--query-local-maps", args.queryLocalMaps,
	             "the queries are local-map images too (of their own drive, centred on the query "
	             "pose) instead of one scan's image");
	app.add_option("--keyframes", args.keyframes,
	               "keyframes a local map, of places and local-map queries (5)")
	    ->check(CLI::Range(1, 32).description(""))
	    ->type_name("N");
	app.add_option("--keyframe-every", args.keyframeEvery_m,
	               "metres between the keyframes of a local map (4)")
	    ->check(CLI::Range(0.5, 100.0).description(""))
	    ->type_name("M");
	app.add_option("--other-towns", args.otherTowns,
	               "also --queries queries from each of N towns not in the database (0)")
	    ->check(CLI::Range(0, 100000).description(""))
	    ->type_name("N");
	auto* kitti =
	    app.add_option("--kitti", args.kitti,
	                   "also the real street of a KITTI folder (velodyne/, calib.txt, "
	                   "poses_semantickitti.txt): places of its real scans, --kitti-queries "
	                   "queries rendered from them at other poses")
	        ->check(CLI::ExistingDirectory.description(""))
	        ->type_name("DIR");
	app.add_option("--kitti-queries", args.kittiQueries, "queries on the KITTI street (20)")
	    ->needs(kitti)
	    ->check(CLI::Range(1, 100000).description(""))
	    ->type_name("N");
	app.add_flag("--polar", gPolar,
	             "also rank the places by polar contexts (each cell of range rings and azimuth "
	             "sectors holds its highest point; compared at the best sector shift), alone and "
	             "fused with the words' ranking; printed after the words' recall");
	app.add_option("--polar-rings", gPolarParams.rings, "--polar: range rings")
	    ->check(CLI::Range(1, 200));
	app.add_option("--polar-sectors", gPolarParams.sectors, "--polar: azimuth sectors")
	    ->check(CLI::Range(1, 720));
	app.add_option("--polar-range", gPolarParams.maxRange_m, "--polar: range of the last ring (m)")
	    ->check(CLI::Range(1.0, 200.0));
	app.add_option("--polar-candidates", gPolarParams.ringCandidates,
	               "--polar: contexts compared in full (a local-map place has one a keyframe), "
	               "chosen by the rings' occupancy")
	    ->check(CLI::Range(1, 100000));
	app.add_option("--fuse-k", gFuseK, "--polar: the constant K of the fusion's 1 / (K + rank)")
	    ->check(CLI::Range(0, 1000));
	app.add_option("--query-turns", gQueryTurns,
	               "each query also rasterized turned by k * 90 / N degrees (k = 1..N-1), its "
	               "candidates the best of the N images' (1: the image as driven)")
	    ->check(CLI::Range(1, 16).description(""))
	    ->type_name("N");
	app.add_option("--turn-weight", gTurnWeight,
	               "--query-turns: weight of the turned images' scores against the image as "
	               "driven (0.8)")
	    ->check(CLI::Range(0.0, 1.0).description(""))
	    ->type_name("W");
	app.add_flag("--canonical", gCanonical,
	             "rasterize each scan turned so that its dominant edges run along the image axes");
	auto* verifyFlag =
	    app.add_flag("--verify", args.verify,
	                 "verify the first --candidates places of each query image against image and "
	                 "judge the accepted place by its registration");
	app.add_option("--candidates", args.candidates, "places verified a query (5)")
	    ->needs(verifyFlag)
	    ->check(CLI::Range(1, 100).description(""))
	    ->type_name("N");
	app.add_option("--min-inliers", args.minInliers,
	               "RANSAC inliers a verified place needs (25, the loop detector's min_inliers)")
	    ->needs(verifyFlag)
	    ->check(CLI::Range(3, 100000).description(""))
	    ->type_name("N");
	app.add_option("--direct-index", gDirectLevels,
	               "match only features under the same vocabulary node this many levels above "
	               "the leaves (a DBoW2 direct index, the loop detector's direct_index_levels_up; "
	               "0: all pairs, the default)")
	    ->needs(verifyFlag)
	    ->check(CLI::Range(0, 8).description(""))
	    ->type_name("L");
	app.add_option("--pose-truth", args.poseTruth_m,
	               "a registration within this of the truth is right (1 m)")
	    ->needs(verifyFlag)
	    ->check(CLI::Range(0.01, 100.0).description(""))
	    ->type_name("M");
	app.add_option("--pose-truth-deg", args.poseTruth_deg,
	               "... and within this of the truth's rotation (3 deg)")
	    ->needs(verifyFlag)
	    ->check(CLI::Range(0.01, 180.0).description(""))
	    ->type_name("DEG");
	app.add_option("--max-height", gMaxHeight,
	               "scans rasterized with only the points up to M above the ground, M grey 255 "
	               "(the rasterizer's max_height_m and grey_max_m, 3 in lifelong.yaml; 0: every "
	               "height, the default)")
	    ->check(CLI::Range(0.0, 100.0).description(""))
	    ->type_name("M");
	app.add_option("--save-images", gSaveImages,
	               "also write each place's image to DIR/NNNNNN.png (to train a vocabulary on "
	               "with rasterslam-vocab train); DIR must exist")
	    ->check(CLI::ExistingDirectory.description(""))
	    ->type_name("DIR");
	if (const int rc = cli::parse(app, argc, argv); rc >= 0)
		return rc;
	mrpt::maps::registerAllClasses_mrpt_maps();
	mrpt::obs::registerAllClasses_mrpt_obs();
	try
	{
		gVerify = args.verify;
		return run(args);
	}
	catch (const std::exception& e)
	{
		std::cerr << "rasterslam-bench-places: error: " << e.what() << "\n";
		return cli::kExitError;
	}
}
