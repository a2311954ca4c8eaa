#include <mrpt/core/initializer.h>
#include <mrpt/serialization/CArchive.h>
#include <mrpt/serialization/stl_serialization.h>
#include <rasterslam/map/keyframe.h>
#include <rasterslam/map/registration.h>

#include <cmath>

using namespace rasterslam;

IMPLEMENTS_SERIALIZABLE(Keyframe, mrpt::serialization::CSerializable, rasterslam)

RASTERSLAM_REGISTER_CLASSES(register_rasterslam_keyframe)
{
	mrpt::rtti::registerClass(CLASS_ID(rasterslam::Keyframe));
}

uint8_t Keyframe::serializeGetVersion() const
{
	return 2;
}

void Keyframe::serializeTo(mrpt::serialization::CArchive& out) const
{
	out << id << session << scanIndex << stamp << pose << u << v << angle << response << octave
	    << xyz << descriptors << static_cast<uint8_t>(groundValid ? 1 : 0) << groundN[0]
	    << groundN[1] << groundN[2] << groundD;
}

void Keyframe::serializeFrom(mrpt::serialization::CArchive& in, uint8_t version)
{
	switch (version)
	{
		case 0:
		case 1:
		case 2:
			in >> id;
			if (version >= 1)
				in >> session;
			else
				session = 0;
			in >> scanIndex >> stamp >> pose >> u >> v >> angle >> response >> octave >> xyz >>
			    descriptors;
			groundValid = false;
			groundN[0] = groundN[1] = 0;
			groundN[2] = 1;
			groundD = 0;
			if (version >= 2)
			{
				// A byte, not a bool: any other value than 0 or 1 read into a bool is undefined
				// (found by fuzz_map_store).
				uint8_t valid = 0;
				in >> valid >> groundN[0] >> groundN[1] >> groundN[2] >> groundD;
				if (valid > 1)
					THROW_EXCEPTION("rasterslam::Keyframe: ground flag not 0 or 1 in the stream");
				groundValid = valid == 1;
				const float norm = std::sqrt(groundN[0] * groundN[0] + groundN[1] * groundN[1] +
				                             groundN[2] * groundN[2]);
				if (groundValid && (!(std::abs(norm - 1) < 1e-3f) || !std::isfinite(groundD)))
					THROW_EXCEPTION("rasterslam::Keyframe: ground normal not unit in the stream");
			}
			break;
		default:
			MRPT_THROW_UNKNOWN_SERIALIZATION_VERSION(version);
	}
	const std::size_t n = u.size();
	if (v.size() != n || angle.size() != n || response.size() != n || octave.size() != n ||
	    xyz.size() != 3 * n || descriptors.size() != 32 * n)
		THROW_EXCEPTION("rasterslam::Keyframe: inconsistent feature arrays in the stream");
}

bool Keyframe::operator==(const Keyframe& o) const
{
	return id == o.id && session == o.session && scanIndex == o.scanIndex && stamp == o.stamp &&
	       pose == o.pose && u == o.u && v == o.v && angle == o.angle && response == o.response &&
	       octave == o.octave && xyz == o.xyz && descriptors == o.descriptors &&
	       groundValid == o.groundValid && groundN[0] == o.groundN[0] &&
	       groundN[1] == o.groundN[1] && groundN[2] == o.groundN[2] && groundD == o.groundD;
}

void Keyframe::releaseFeatures()
{
	for (auto* f : {&u, &v, &angle, &response})
	{
		f->clear();
		f->shrink_to_fit();
	}
	octave.clear();
	octave.shrink_to_fit();
	xyz.clear();
	xyz.shrink_to_fit();
	descriptors.clear();
	descriptors.shrink_to_fit();
}
