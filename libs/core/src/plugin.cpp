#include <rasterslam/core/plugin.h>

using namespace rasterslam;

IMPLEMENTS_VIRTUAL_MRPT_OBJECT(Plugin, mrpt::rtti::CObject, rasterslam)
IMPLEMENTS_VIRTUAL_MRPT_OBJECT(Rasterizer, Plugin, rasterslam)
IMPLEMENTS_VIRTUAL_MRPT_OBJECT(Odometry, Plugin, rasterslam)
IMPLEMENTS_VIRTUAL_MRPT_OBJECT(MapManager, Plugin, rasterslam)
IMPLEMENTS_VIRTUAL_MRPT_OBJECT(LoopDetector, Plugin, rasterslam)
IMPLEMENTS_VIRTUAL_MRPT_OBJECT(Optimizer, Plugin, rasterslam)

void Plugin::initialize(const mrpt::containers::yaml& params, const std::string& source)
{
	ParamReader reader(params, role() + ".params", source);
	initializeImpl(reader);
	reader.finish();
	paramsInForce_ = reader.inForce();
}

const char* rasterslam::toString(TrackingStatus s)
{
	switch (s)
	{
		case TrackingStatus::Initializing:
			return "init";
		case TrackingStatus::Ok:
			return "ok";
		case TrackingStatus::Lost:
			return "lost";
	}
	return "?";
}
