// A keyframe: the pose-graph node the tracking creates, with what was seen there.
#pragma once

#include <mrpt/poses/CPose3D.h>
#include <mrpt/serialization/CSerializable.h>

#include <cstdint>
#include <vector>

namespace rasterslam
{
/** Paper, "Laser Pose Estimation": "Each keyframe stores the 6dof pose and 3d values of all
 *  the features observed at that position." Features are ORB keypoints of the keyframe's
 *  elevation image: image position, octave, angle, response, 32-byte descriptor and the 3D
 *  point behind the pixel (vehicle frame of the keyframe). Serialized with a version. */
class Keyframe : public mrpt::serialization::CSerializable
{
	DEFINE_SERIALIZABLE(Keyframe, rasterslam)

   public:
	uint64_t id = 0;       //!< pose-graph node id, unique across the sessions of a map
	uint32_t session = 0;  //!< the session (run) that made it
	uint64_t scanIndex = 0;
	double stamp = 0;
	/** In the map frame as saved. While running, the engine's pose graph owns the pose:
	 *  read it from there (PoseView), not from here. */
	mrpt::poses::CPose3D pose;

	std::vector<float> u, v, angle, response;  //!< one entry a feature
	std::vector<uint8_t> octave;
	std::vector<float> xyz;            //!< 3 floats a feature
	std::vector<uint8_t> descriptors;  //!< 32 bytes a feature

	/** The ground plane the rasterizer found in the keyframe's scan, in its vehicle frame:
	 *  n . p + d = height above the ground (n unit, up). Relocalization takes height, roll and
	 *  pitch from it. Kept when the features are released; maps saved before it have none. */
	bool groundValid = false;
	float groundN[3] = {0, 0, 1};
	float groundD = 0;

	std::size_t size() const { return u.size(); }
	/** Drops the features (the keyframe's local maps hold them as map points). */
	void releaseFeatures();
	bool operator==(const Keyframe& o) const;
};

}  // namespace rasterslam
