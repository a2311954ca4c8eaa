// libFuzzer target for the map files. The first byte of an input chooses the reader, the rest
// is the file:
//   0: a local-map store file (NNNNNN.rslm: header, CRC-32, payload) read by
//      LocalMapStore::load, as it is (most damage stops at the checksum);
//   1: the payload of a store file only: the target writes a valid header with the payload's
//      CRC-32 in front, so that the MRPT-serialized LocalMap behind the checksum is fuzzed;
//   2: a map index (DIR/map.rsmap, gzip or plain MRPT archive) read by rasterslam::loadMap,
//      then every local map's data read through Map::data. Version 4 checks a CRC-32 of the
//      body first; the seeds include the same body as version 3 (no checksum), so that the
//      body's parser is fuzzed too. DIR/store is a link to
//      $RASTERSLAM_FUZZ_MAP_STORE when set (the store of the map the seeds were made from,
//      fuzz/make-corpus.sh), so that an index naming its files gets past the file check.
// Errors (exceptions) are expected; crashes, leaks, undefined behaviour, hangs and unbounded
// allocations are findings.
#include <mrpt/system/crc.h>
#include <rasterslam/map/local_map_store.h>
#include <rasterslam/map/map.h>

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <filesystem>
#include <string>
#include <vector>

#include "fuzz_common.h"

namespace fs = std::filesystem;

namespace
{
constexpr uint32_t kStoreMagic = 0x4d4c5352;  // "RSLM", as libs/map/src/local_map_store.cpp
constexpr uint64_t kLocalMap = 1;             // the id the store file is read as

const std::string& storeDir()
{
	static const std::string dir = []
	{
		const auto d = rasterslam::fuzz::scratchDir() + "/store";
		fs::create_directories(d);
		return d;
	}();
	return dir;
}

/** DIR of a map: DIR/store links to the seeds' store, or is an empty folder. */
const std::string& mapDir()
{
	static const std::string dir = []
	{
		const auto d = rasterslam::fuzz::scratchDir() + "/map";
		fs::create_directories(d);
		if (const char* store = std::getenv("RASTERSLAM_FUZZ_MAP_STORE"); store && *store)
			fs::create_directory_symlink(fs::absolute(store), d + "/store");
		return d;
	}();
	return dir;
}

void readStoreFile(const uint8_t* data, std::size_t size)
{
	const rasterslam::LocalMapStore store(storeDir());
	rasterslam::fuzz::writeFile(store.pathOf(kLocalMap), data, size);
	try
	{
		const auto lm = store.load(kLocalMap);
		(void)lm->points();
		(void)lm->hasData();
	}
	catch (const std::exception&)
	{
	}
}

void readStorePayload(const uint8_t* data, std::size_t size)
{
	std::vector<uint8_t> file(17 + size);
	const uint64_t n = size;
	const uint32_t crc = mrpt::system::compute_CRC32(data, size);
	const uint8_t version = 0;
	std::memcpy(file.data(), &kStoreMagic, 4);
	std::memcpy(file.data() + 4, &version, 1);
	std::memcpy(file.data() + 5, &n, 8);
	std::memcpy(file.data() + 13, &crc, 4);
	if (size)
		std::memcpy(file.data() + 17, data, size);
	readStoreFile(file.data(), file.size());
}

void readMap(const uint8_t* data, std::size_t size)
{
	rasterslam::fuzz::writeFile(rasterslam::mapFilePath(mapDir()), data, size);
	try
	{
		const auto map = rasterslam::loadMap(mapDir());
		(void)map.memoryBytes();
		(void)map.nextKeyframeId();
		(void)map.nextLocalMapId();
		for (const auto& [id, lm] : map.localMaps)
		{
			try
			{
				(void)map.data(id)->points();
			}
			catch (const std::exception&)
			{
			}
		}
		for (const auto& [id, kf] : map.keyframes)
			(void)map.localMapsOf(id);
	}
	catch (const std::exception&)
	{
	}
}
}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***)
{
	rasterslam::fuzz::registerProjectClasses();
	return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, std::size_t size)
{
	if (size < 1)
		return 0;
	switch (data[0] % 3)
	{
		case 0:
			readStoreFile(data + 1, size - 1);
			break;
		case 1:
			readStorePayload(data + 1, size - 1);
			break;
		default:
			readMap(data + 1, size - 1);
			break;
	}
	return 0;
}
