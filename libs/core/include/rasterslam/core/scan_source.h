// Where scans come from (a rawlog, a KITTI folder, a simulator...).
#pragma once

#include <rasterslam/core/types.h>

#include <optional>
#include <string>

namespace rasterslam
{
class ScanSource
{
   public:
	virtual ~ScanSource() = default;
	/** The next scan, or nullopt when the input ends, normally or at damage (then
	 *  stopReason() says where and why). Throws for input that cannot be read at all. */
	virtual std::optional<Scan> next() = 0;
	/** What is being read, for messages (e.g. the file path). */
	virtual std::string name() const = 0;
	/** Fraction of the input consumed, 0..1, or negative when unknown. */
	virtual double progress() const { return -1; }
	/** Empty after a normal end; otherwise why reading stopped early. */
	virtual std::string stopReason() const { return {}; }
};

}  // namespace rasterslam
