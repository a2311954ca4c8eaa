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

	/** Writes a local map (its points and image included) as pathOf(id); returns the bytes
	 *  written. */
	std::size_t save(const LocalMap& lm) const;
	/** Reads one back; throws naming the file when it is missing, damaged or another map. */
	LocalMap::Ptr load(uint64_t localMap) const;
	bool contains(uint64_t localMap) const;

	/** A local map in a saved map's store, named by its id and content. */
	struct Entry
	{
		std::string file;  //!< name in the folder: NNNNNN-CCCCCCCC.rslm (id, payload CRC-32)
		uint64_t points = 0, bytes = 0;
	};
	/** Writes a local map under a name made of its id and its content's checksum: a file is
	 *  never rewritten with other content, so a map whose index still names it (a save
	 *  interrupted before its new index was in place) stays whole. Skips the write when the
	 *  file is there already. */
	Entry saveContent(const LocalMap& lm) const;
	/** Reads a file of the folder; throws naming it when it is missing, damaged or holds
	 *  another local map than `localMap`. */
	LocalMap::Ptr loadFile(const std::string& file, uint64_t localMap) const;

   private:
	LocalMap::Ptr loadPath(const std::string& path, uint64_t localMap) const;
	std::string dir_;
};

}  // namespace rasterslam
