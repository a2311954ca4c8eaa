// The offline store of the paper's map management: local maps that left the online graph,
// one file each, read back on demand.
#pragma once

#include <rasterslam/map/local_map.h>

#include <string>

namespace rasterslam
{
/** A folder of `NNNNNN.rslm` files, one local map each: magic, version, payload length,
 *  CRC-32 of the payload, and the payload (the MRPT-serialized LocalMap). Files are written
 *  under a temporary name and renamed, so a file is either whole or absent; a damaged one
 *  fails its checksum on reading. */
class LocalMapStore
{
   public:
	/** Creates the folder if needed. */
	explicit LocalMapStore(std::string dir);
	const std::string& dir() const { return dir_; }
	std::string pathOf(uint64_t localMap) const;

	/** Writes a local map (its points and image included); returns the bytes written. */
	std::size_t save(const LocalMap& lm) const;
	/** Reads one back; throws naming the file when it is missing, damaged or another map. */
	LocalMap::Ptr load(uint64_t localMap) const;
	bool contains(uint64_t localMap) const;

   private:
	std::string dir_;
};

}  // namespace rasterslam
