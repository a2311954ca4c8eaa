// The paper's rasterizer: outlier removal, RANSAC ground removal, projection of the remaining
// points into a greyscale elevation image (orthographic bird's-eye view or equation (1)).
#include <mrpt/core/initializer.h>
#include <rasterslam/core/plugin.h>
#include <rasterslam/map/registration.h>
#include <rasterslam/raster/elevation_image.h>
#include <rasterslam/raster/ground_plane.h>

namespace rasterslam
{
class ElevationRasterizer : public Rasterizer
{
	DEFINE_MRPT_OBJECT(ElevationRasterizer, rasterslam)

   public:
	void rasterize(const Scan& scan, RasterFrame& out) override;
	const raster::RasterParams& params() const { return raster_; }

   protected:
	void initializeImpl(ParamReader& p) override;

   private:
	raster::RasterParams raster_;
	raster::GroundParams ground_;
};
}  // namespace rasterslam

using namespace rasterslam;

IMPLEMENTS_MRPT_OBJECT(ElevationRasterizer, Rasterizer, rasterslam)

RASTERSLAM_REGISTER_CLASSES(register_rasterslam_plugin_elevation_rasterizer)
{
	mrpt::rtti::registerClass(CLASS_ID(rasterslam::ElevationRasterizer));
}

void ElevationRasterizer::initializeImpl(ParamReader& p)
{
	raster::RasterParams r;
	r.mode = p.getChoice("projection", "bev", {"bev", "pinhole"}) == "bev"
	             ? raster::ProjectionMode::Bev
	             : raster::ProjectionMode::Pinhole;
	r.minRange_m = p.getDouble("min_range_m", r.minRange_m);
	r.maxRange_m = p.getDouble("max_range_m", r.maxRange_m);
	r.resolution_m = p.getDouble("resolution_m", r.resolution_m);
	r.pinholeSize_px = p.getInt("pinhole_size_px", r.pinholeSize_px);
	r.cameraHeight_m = p.getDouble("camera_height_m", r.cameraHeight_m);
	r.sensorHeight_m = p.getDouble("sensor_height_m", r.sensorHeight_m);
	r.removeGround = p.getBool("remove_ground", r.removeGround);
	r.groundThreshold_m = p.getDouble("ground_threshold_m", r.groundThreshold_m);
	r.belowGround_m = p.getDouble("below_ground_m", r.belowGround_m);
	r.maxHeight_m = p.getDouble("max_height_m", r.maxHeight_m);
	r.greyMin_m = p.getDouble("grey_min_m", r.greyMin_m);
	r.greyMax_m = p.getDouble("grey_max_m", r.greyMax_m);
	r.equalize = p.getBool("equalize", r.equalize);
	r.canonicalYaw = p.getBool("canonical_yaw", r.canonicalYaw);
	raster::GroundParams g;
	g.candidateMaxZ_m = p.getDouble("ground_candidate_max_z_m", g.candidateMaxZ_m);
	g.candidateMaxRange_m = p.getDouble("ground_candidate_max_range_m", g.candidateMaxRange_m);
	g.layerMargin_m = p.getDouble("ground_candidate_layer_margin_m", g.layerMargin_m);
	g.maxCandidates = p.getInt("ground_max_candidates", g.maxCandidates);
	g.iterations = p.getInt("ground_ransac_iterations", g.iterations);
	g.inlierThreshold_m = p.getDouble("ground_inlier_threshold_m", g.inlierThreshold_m);
	g.maxTilt_deg = p.getDouble("ground_max_tilt_deg", g.maxTilt_deg);
	p.requireAtLeast(r.minRange_m, 0, "min_range_m");
	p.requirePositive(r.maxRange_m, "max_range_m");
	p.requirePositive(r.resolution_m, "resolution_m");
	p.requirePositive(r.pinholeSize_px, "pinhole_size_px");
	p.requirePositive(r.cameraHeight_m, "camera_height_m");
	p.requirePositive(r.sensorHeight_m, "sensor_height_m");
	p.requireAtLeast(r.groundThreshold_m, 0, "ground_threshold_m");
	p.requireAtLeast(r.belowGround_m, 0, "below_ground_m");
	p.requireAtLeast(r.maxHeight_m, 0, "max_height_m");
	p.require(r.greyMax_m > r.greyMin_m, r.greyMax_m, "grey_max_m", "must be above grey_min_m");
	p.requirePositive(g.candidateMaxRange_m, "ground_candidate_max_range_m");
	p.requireRange(g.layerMargin_m, 0, 2, "ground_candidate_layer_margin_m");
	p.requireAtLeast(g.maxCandidates, 3, "ground_max_candidates");  // a plane takes 3 points
	p.requireAtLeast(g.iterations, 1, "ground_ransac_iterations");
	p.requirePositive(g.inlierThreshold_m, "ground_inlier_threshold_m");
	p.requireRange(g.maxTilt_deg, 0, 90, "ground_max_tilt_deg");
	p.require(r.minRange_m < r.maxRange_m, r.minRange_m, "min_range_m",
	          "must be below max_range_m");
	if (r.mode == raster::ProjectionMode::Bev && 2 * r.maxRange_m / r.resolution_m > 8192)
		p.reject("resolution_m", "the image would exceed 8192 pixels a side");
	raster_ = r;
	ground_ = g;
}

void ElevationRasterizer::rasterize(const Scan& scan, RasterFrame& out)
{
	// The plane is fitted even without ground removal: grey levels are heights above it.
	const raster::Plane plane =
	    raster::fitGroundPlane(scan.points, ground_, static_cast<uint32_t>(scan.index + 1));
	const auto st = raster::rasterizeElevation(scan.points, plane, raster_, out);
	out.groundValid = plane.valid;
	out.groundNormal[0] = plane.n.x();
	out.groundNormal[1] = plane.n.y();
	out.groundNormal[2] = plane.n.z();
	out.groundD = plane.d;
	MRPT_LOG_DEBUG_FMT(
	    "scan %zu: %zu points, %zu outliers, %zu ground (plane %s), %zu projected into %zu pixels",
	    scan.index, st.input, st.outliers, st.ground, plane.valid ? "found" : "not found",
	    st.projected, st.pixels);
}
