#include <fcntl.h>
#include <mrpt/io/CFileInputStream.h>
#include <mrpt/io/CFileOutputStream.h>
#include <mrpt/io/CMemoryStream.h>
#include <mrpt/serialization/CArchive.h>
#include <mrpt/system/crc.h>
#include <rasterslam/map/local_map_store.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <stdexcept>

namespace fs = std::filesystem;

namespace rasterslam
{
namespace
{
constexpr uint32_t kStoreMagic = 0x4d4c5352;  // "RSLM"
constexpr uint8_t kStoreVersion = 0;
// A local map is a few hundred kB; anything past this is a damaged length, not a map.
constexpr uint64_t kMaxPayload = uint64_t(1) << 31;
}  // namespace

LocalMapStore::LocalMapStore(std::string dir) : dir_(std::move(dir))
{
	fs::create_directories(dir_);
}

std::string LocalMapStore::pathOf(uint64_t localMap) const
{
	return (fs::path(dir_) / mrpt::format("%06llu.rslm", static_cast<unsigned long long>(localMap)))
	    .string();
}

bool LocalMapStore::contains(uint64_t localMap) const
{
	std::error_code ec;
	return fs::is_regular_file(pathOf(localMap), ec);
}

namespace
{
struct Payload
{
	mrpt::io::CMemoryStream buf;
	const uint8_t* bytes = nullptr;
	uint64_t n = 0;
	uint32_t crc = 0;
	explicit Payload(const LocalMap& lm)
	{
		mrpt::serialization::archiveFrom(buf) << lm;
		bytes = static_cast<const uint8_t*>(buf.getRawBufferData());
		n = buf.getTotalBytesCount();
		crc = mrpt::system::compute_CRC32(bytes, n);
	}
};

/** Header and payload under a temporary name, then renamed onto `path`. */
void writeFile(const std::string& path, const Payload& payload)
{
	const uint64_t n = payload.n;
	const uint32_t crc = payload.crc;
	const auto tmp = path + ".tmp-" + std::to_string(::getpid());
	{
		std::ofstream f(tmp, std::ios::binary | std::ios::trunc);
		auto put = [&](const void* p, std::size_t k)
		{ f.write(static_cast<const char*>(p), static_cast<std::streamsize>(k)); };
		put(&kStoreMagic, 4);
		put(&kStoreVersion, 1);
		put(&n, 8);
		put(&crc, 4);
		put(payload.bytes, n);
		f.flush();
		f.close();
		if (!f)
		{
			std::error_code ec;
			fs::remove(tmp, ec);
			throw std::runtime_error("cannot write local map '" + path +
			                         "': " + std::strerror(errno) + " (disk full?)");
		}
	}
	// On the disk before it is named: an index that survives a power cut must find it whole.
	if (const int fd = ::open(tmp.c_str(), O_RDONLY); fd >= 0)
	{
		::fsync(fd);
		::close(fd);
	}
	fs::rename(tmp, path);
}
}  // namespace

std::size_t LocalMapStore::save(const LocalMap& lm) const
{
	const Payload p(lm);
	writeFile(pathOf(lm.id), p);
	return 17 + p.n;
}

LocalMapStore::Entry LocalMapStore::saveContent(const LocalMap& lm) const
{
	const Payload p(lm);
	Entry e;
	e.file = mrpt::format("%06llu-%08x.rslm", static_cast<unsigned long long>(lm.id), p.crc);
	e.points = lm.points();
	e.bytes = 17 + p.n;
	std::error_code ec;
	const auto path = (fs::path(dir_) / e.file).string();
	if (!(fs::is_regular_file(path, ec) && fs::file_size(path, ec) == e.bytes))
		writeFile(path, p);
	return e;
}

LocalMap::Ptr LocalMapStore::loadFile(const std::string& file, uint64_t localMap) const
{
	if (file.empty() || file.find('/') != std::string::npos || file.find("..") != std::string::npos)
		throw std::runtime_error("local map " + std::to_string(localMap) + ": bad file name '" +
		                         file + "'");
	return loadPath((fs::path(dir_) / file).string(), localMap);
}

LocalMap::Ptr LocalMapStore::load(uint64_t localMap) const
{
	return loadPath(pathOf(localMap), localMap);
}

LocalMap::Ptr LocalMapStore::loadPath(const std::string& path, uint64_t localMap) const
{
	auto fail = [&](const std::string& what)
	{ return std::runtime_error("cannot read local map '" + path + "': " + what); };
	std::ifstream f(path, std::ios::binary);
	if (!f)
		throw fail("no such file");
	uint32_t magic = 0, crc = 0;
	uint8_t version = 0;
	uint64_t n = 0;
	f.read(reinterpret_cast<char*>(&magic), 4);
	f.read(reinterpret_cast<char*>(&version), 1);
	f.read(reinterpret_cast<char*>(&n), 8);
	f.read(reinterpret_cast<char*>(&crc), 4);
	if (!f)
		throw fail("truncated header");
	if (magic != kStoreMagic)
		throw fail("not a rasterslam local map");
	if (version != kStoreVersion)
		throw fail("unknown version " + std::to_string(version));
	std::error_code ec;
	const auto size = fs::file_size(path, ec);
	if (n > kMaxPayload || ec || size != 17 + n)
		throw fail("length " + std::to_string(n) + " does not match the file size " +
		           std::to_string(size));
	std::vector<uint8_t> bytes(n);
	f.read(reinterpret_cast<char*>(bytes.data()), static_cast<std::streamsize>(n));
	if (!f)
		throw fail("truncated payload");
	if (mrpt::system::compute_CRC32(bytes) != crc)
		throw fail("checksum mismatch (the file is damaged)");
	mrpt::io::CMemoryStream buf;
	buf.assignMemoryNotOwn(bytes.data(), bytes.size());
	LocalMap::Ptr lm;
	try
	{
		lm =
		    std::dynamic_pointer_cast<LocalMap>(mrpt::serialization::archiveFrom(buf).ReadObject());
	}
	catch (const std::exception& e)
	{
		std::string what = e.what();
		if (const auto pos = what.find("Call stack"); pos != std::string::npos)
			what.resize(pos);
		throw fail(what);
	}
	if (!lm)
		throw fail("holds no local map");
	if (lm->id != localMap)
		throw fail("holds local map " + std::to_string(lm->id));
	return lm;
}

}  // namespace rasterslam
