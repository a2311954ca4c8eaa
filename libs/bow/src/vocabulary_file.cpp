// Vocabulary files: gzip of "RSVB", a version, the body's length and CRC-32, then the MRPT
// serialization of the vocabulary. Older files hold the MRPT object alone.
#include <mrpt/io/CFileGZInputStream.h>
#include <mrpt/io/CFileGZOutputStream.h>
#include <mrpt/io/CMemoryStream.h>
#include <mrpt/serialization/CArchive.h>
#include <mrpt/system/crc.h>
#include <rasterslam/bow/vocabulary.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <stdexcept>

namespace fs = std::filesystem;

namespace rasterslam::bow
{
namespace
{
constexpr uint32_t kVocabMagic = 0x42565352;  // "RSVB"
constexpr uint8_t kVocabFileVersion = 1;
constexpr uint64_t kMaxBody = uint64_t(2) << 30;

std::string innermost(const std::exception& e)
{
	std::string what = e.what();
	if (const auto pos = what.find("Message:"); pos != std::string::npos)
		what = what.substr(pos + 9, what.find('\n', pos) - pos - 9);
	if (const auto pos = what.find("Call stack"); pos != std::string::npos)
		what.resize(pos);
	while (!what.empty() && (what.back() == '\n' || what.back() == ' '))
		what.pop_back();
	return what;
}

std::shared_ptr<Vocabulary> fromArchive(mrpt::serialization::CArchive& a)
{
	auto v = std::dynamic_pointer_cast<Vocabulary>(a.ReadObject());
	if (!v)
		throw std::runtime_error("holds no rasterslam::bow::Vocabulary");
	return v;
}
}  // namespace

void saveVocabularyFile(const Vocabulary& vocabulary, const std::string& path)
{
	mrpt::io::CMemoryStream body;
	mrpt::serialization::archiveFrom(body) << vocabulary;
	const auto* bytes = static_cast<const uint8_t*>(body.getRawBufferData());
	const uint64_t n = body.getTotalBytesCount();
	const uint32_t crc = mrpt::system::compute_CRC32(bytes, n);
	const std::string tmp = path + ".tmp-" + std::to_string(::getpid());
	try
	{
		mrpt::io::CFileGZOutputStream f;
		if (!f.open(tmp))
			throw std::runtime_error("cannot open for writing");
		auto a = mrpt::serialization::archiveFrom(f);
		a << kVocabMagic << kVocabFileVersion << n << crc;
		if (f.Write(bytes, n) != n)
			throw std::runtime_error("cannot write (disk full?)");
		f.close();
		fs::rename(tmp, path);
	}
	catch (const std::exception& e)
	{
		std::error_code ec;
		fs::remove(tmp, ec);
		throw std::runtime_error("vocabulary '" + path + "': " + innermost(e));
	}
}

std::shared_ptr<Vocabulary> loadVocabularyFile(const std::string& path)
{
	const auto fail = [&](const std::string& what)
	{ return std::runtime_error("vocabulary '" + path + "': " + what); };
	std::error_code ec;
	if (!fs::exists(path, ec))
		throw fail("no such file");
	if (!fs::is_regular_file(path, ec))
		throw fail("not a file");
	try
	{
		mrpt::io::CFileGZInputStream f;
		if (!f.open(path))
			throw std::runtime_error("cannot open");
		uint32_t magic = 0;
		if (f.Read(&magic, 4) == 4 && magic == kVocabMagic)
		{
			auto a = mrpt::serialization::archiveFrom(f);
			uint8_t version = 0;
			uint64_t n = 0;
			uint32_t crc = 0;
			a >> version >> n >> crc;
			if (version != kVocabFileVersion)
				throw std::runtime_error("unknown vocabulary file version " +
				                         std::to_string(version));
			if (n > kMaxBody)
				throw std::runtime_error("damaged header: a body of " + std::to_string(n) +
				                         " bytes");
			std::vector<uint8_t> bytes;
			constexpr uint64_t kStep = uint64_t(16) << 20;
			while (bytes.size() < n)
			{
				const auto had = bytes.size();
				const auto want = std::min<uint64_t>(kStep, n - had);
				bytes.resize(had + want);
				if (f.Read(bytes.data() + had, want) != want)
					throw std::runtime_error("truncated: the body is " + std::to_string(n) +
					                         " bytes, the file ends after " + std::to_string(had) +
					                         " of them");
			}
			if (mrpt::system::compute_CRC32(bytes) != crc)
				throw std::runtime_error("checksum mismatch (the file is damaged)");
			mrpt::io::CMemoryStream body;
			body.assignMemoryNotOwn(bytes.data(), bytes.size());
			auto b = mrpt::serialization::archiveFrom(body);
			return fromArchive(b);
		}
		// An older file: the MRPT object alone, no checksum.
		mrpt::io::CFileGZInputStream g;
		if (!g.open(path))
			throw std::runtime_error("cannot open");
		auto a = mrpt::serialization::archiveFrom(g);
		return fromArchive(a);
	}
	catch (const std::exception& e)
	{
		throw fail(innermost(e));
	}
}

}  // namespace rasterslam::bow
