// A plugin module built for another plugin ABI (its mark, old_abi_mark.cpp, says 0): the
// loader must refuse it and its class, and give back the name of a class it registered over
// another's. Built for test_plugins only, outside the plugin folder.
#include <rasterslam/core/plugin.h>
#include <rasterslam/map/registration.h>

namespace rasterslam_test
{
class OldAbiRasterizer : public rasterslam::Rasterizer
{
	DEFINE_MRPT_OBJECT(OldAbiRasterizer, rasterslam_test)

   public:
	void rasterize(const rasterslam::Scan&, rasterslam::RasterFrame&) override {}

   protected:
	void initializeImpl(rasterslam::ParamReader&) override {}
};

/** Registered under the name of a class test_plugins registers itself: a refused module must
 *  not take that name from it. */
class ShadowingRasterizer : public rasterslam::Rasterizer
{
	DEFINE_MRPT_OBJECT(ShadowingRasterizer, rasterslam_test)

   public:
	void rasterize(const rasterslam::Scan&, rasterslam::RasterFrame&) override {}

   protected:
	void initializeImpl(rasterslam::ParamReader&) override {}
};
}  // namespace rasterslam_test

IMPLEMENTS_MRPT_OBJECT(OldAbiRasterizer, rasterslam::Rasterizer, rasterslam_test)
INTERNAL_IMPLEMENTS_MRPT_OBJECT(ShadowingRasterizer, rasterslam::Rasterizer, rasterslam_test,
                                "rasterslam_test::ShadowedRasterizer")

RASTERSLAM_REGISTER_CLASSES(register_rasterslam_test_old_abi)
{
	mrpt::rtti::registerClass(CLASS_ID(rasterslam_test::OldAbiRasterizer));
	mrpt::rtti::registerClass(CLASS_ID(rasterslam_test::ShadowingRasterizer));
}
