// libFuzzer target: an input is a rawlog file (either format, gzip or plain) read by
// rasterslam::io::RawlogSource to its end. Errors (exceptions) are expected; crashes, leaks,
// undefined behaviour, hangs and unbounded allocations are findings.
#include <rasterslam/io/rawlog_source.h>

#include <cstddef>
#include <cstdint>
#include <exception>

#include "fuzz_common.h"

extern "C" int LLVMFuzzerInitialize(int*, char***)
{
	rasterslam::fuzz::registerProjectClasses();
	return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, std::size_t size)
{
	const auto path = rasterslam::fuzz::inputFile("input.rawlog", data, size);
	try
	{
		rasterslam::io::RawlogSource src(path);
		while (auto scan = src.next())
		{
			// Touch every point: a scan must hold what it says it holds.
			float sum = 0;
			for (const auto& p : scan->points)
				sum += p.x + p.y + p.z + p.intensity;
			(void)sum;
		}
		(void)src.progress();
		(void)src.stopReason();
	}
	catch (const std::exception&)
	{
	}
	return 0;
}
