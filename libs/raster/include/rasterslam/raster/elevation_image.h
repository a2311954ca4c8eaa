// Projection of a scan (or of a local map's points) into a greyscale elevation image.
#pragma once

#include <rasterslam/core/plugin.h>
#include <rasterslam/raster/ground_plane.h>

#include <Eigen/Geometry>
#include <opencv2/core/mat.hpp>
#include <string>
#include <vector>

namespace rasterslam::raster
{
enum class ProjectionMode
{
	/** Orthographic bird's-eye view: a fixed number of metres per pixel. */
	Bev,
	/** The paper's pinhole model, equation (1): z_i = K R (I|t) z_l, a camera above the
	 *  sensor looking down with its z axis (the optical axis) along the LiDAR's -z. */
	Pinhole
};

struct RasterParams
{
	ProjectionMode mode = ProjectionMode::Bev;
	/** Outlier removal: points outside this horizontal range window are dropped. */
	double minRange_m = 2.0, maxRange_m = 50.0;
	/** Points more than this below the ground plane are outliers (reflections, noise). */
	double belowGround_m = 0.5;
	/** Points higher than this above the ground are dropped (a ceiling indoors would cover
	 *  every pixel); 0: no limit. */
	double maxHeight_m = 0;
	/** Ground removal: points within this height of the plane are ground. */
	bool removeGround = true;
	double groundThreshold_m = 0.25;
	/** Height of the sensor above the ground, used when no ground plane was found. */
	double sensorHeight_m = 1.73;
	/** Grey levels: height above ground mapped linearly from [greyMin_m, greyMax_m] to
	 *  1..255 (0 marks an empty pixel); with `equalize`, the levels of the occupied pixels
	 *  are then histogram-equalized, which spreads the contrast FAST and ORB see. */
	double greyMin_m = 0.0, greyMax_m = 8.0;
	bool equalize = true;
	/** BEV: metres per pixel; the image covers +-maxRange_m around the sensor. */
	double resolution_m = 0.2;
	/** Pinhole: image size (square) and camera height above the sensor; the focal length
	 *  makes the ground at +-maxRange_m reach the image border. */
	int pinholeSize_px = 500;
	double cameraHeight_m = 20.0;
	/** BEV only: turn the image so that the scene's dominant edges run along its axes (the
	 *  peak of the gradient orientations of a first image, modulo 90 degrees), so that a
	 *  place seen turned by any angle gives the same pixel grid (ORB's orientation does not
	 *  undo a changed pixelization). RasterFrame::imageYaw records the turn; pixelToPoint
	 *  still indexes the input points. Costs a second pass. */
	bool canonicalYaw = false;
};

/** How a local-map image is rasterized (the map manager's images and the queries made like
 *  them): keyframes' non-ground points already moved into one frame, `resolution_m` a pixel
 *  over +-`extent_m`, no range window, no ground removal and no outlier cut below it (the
 *  points hold no ground; rasterize with an invalid plane). */
inline RasterParams localMapRasterParams(double resolution_m = 0.2, double extent_m = 60.0)
{
	RasterParams p;
	p.resolution_m = resolution_m;
	p.maxRange_m = extent_m;
	p.minRange_m = 0;
	p.removeGround = false;
	p.belowGround_m = 1e6;
	return p;
}

/** Appends `pts` moved by `T` (p' = T p, intensities kept) to `out`: how keyframes' points
 *  are gathered into one local map's frame before localMapRasterParams() rasterizes them. */
void appendMoved(const std::vector<PointXYZI>& pts, const Eigen::Isometry3f& T,
                 std::vector<PointXYZI>& out);

/** Appends to `out` the points of `pts` that `f` shows (the highest of each occupied pixel,
 *  f.pixelToPoint's), in pixel order: a scan's points with the ground and outliers removed,
 *  as the local maps gather them. */
void appendImagePoints(const RasterFrame& f, const std::vector<PointXYZI>& pts,
                       std::vector<PointXYZI>& out);

struct RasterStats
{
	std::size_t input = 0, outliers = 0, ground = 0, projected = 0, pixels = 0;
	Plane plane;
};

/** Projects `pts` (sensor/vehicle frame) into `out`: an 8-bit image whose grey level encodes
 *  the height above the ground of the highest point of each pixel, and for each pixel the
 *  index of that point in `pts` (-1 when empty). `ground` may be invalid (then heights are
 *  z + sensorHeight_m). */
RasterStats rasterizeElevation(const std::vector<PointXYZI>& pts, const Plane& ground,
                               const RasterParams& p, RasterFrame& out);

/** As rasterizeElevation, with the points turned by `yaw` (radians, counter-clockwise about
 *  z) before the projection, whatever p.canonicalYaw says; out.imageYaw = yaw. */
RasterStats rasterizeElevationTurned(const std::vector<PointXYZI>& pts, const Plane& ground,
                                     const RasterParams& p, float yaw, RasterFrame& out);

/** The dominant direction of an 8-bit image's edges modulo 90 degrees, in [0, pi/2): the
 *  peak of the gradient orientations weighted by magnitude, 1-degree bins smoothed, refined
 *  between bins. */
double dominantEdgeAngle(const cv::Mat& img);

/** Pixel (u, v) of a point for the given parameters (floating point; may lie outside). */
bool projectPoint(const RasterParams& p, float x, float y, float z, float& u, float& v);

/** The point behind a pixel, or behind the nearest occupied pixel within `radius_px`
 *  (keypoints sit on corners, next to empty pixels). Returns -1 when there is none. */
int32_t pointAtPixel(const RasterFrame& f, float u, float v, int radius_px = 1);

}  // namespace rasterslam::raster
