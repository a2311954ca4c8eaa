// A module that does not include plugin.h (as one built before plugin ABI marks): it uses
// rasterslam's core library, which carries the mark, so the loader must check that the mark
// it finds is the module's own.
#include <rasterslam/core/config.h>

extern "C" std::size_t rasterslam_test_unmarked()
{
	return rasterslam::configLocation("unmarked.yaml", "a.b").size();  // needs the core library
}
