// libFuzzer target: an input is a vocabulary file (gzip or plain MRPT archive) loaded as the
// project loads one (rasterslam::bow::loadVocabularyFile when libs/bow has it, else as the
// loop detector does: CFileGZInputStream, ReadObject, a cast to rasterslam::bow::Vocabulary),
// then used: a few descriptors are turned into bags of words with their direct index, as a
// loop query does, so that a tree whose links or words do not hold together is caught.
// Errors (exceptions) are expected; crashes, leaks, undefined behaviour, hangs and unbounded
// allocations are findings.
#include <rasterslam/bow/vocabulary.h>

#include <cstddef>
#include <cstdint>
#include <exception>
#include <memory>
#include <vector>

#include "fuzz_common.h"
#ifdef RASTERSLAM_FUZZ_VOCABULARY_HEADER
#include RASTERSLAM_FUZZ_VOCABULARY_HEADER
#else
#include <mrpt/io/CFileGZInputStream.h>
#include <mrpt/serialization/CArchive.h>
#endif

namespace
{
std::shared_ptr<rasterslam::bow::Vocabulary> load(const std::string& path)
{
#ifdef RASTERSLAM_FUZZ_VOCABULARY_HEADER
	auto v = rasterslam::bow::loadVocabularyFile(path);
	using V = decltype(v);
	if constexpr (std::is_same_v<V, rasterslam::bow::Vocabulary>)
		return std::make_shared<rasterslam::bow::Vocabulary>(std::move(v));
	else
		return std::shared_ptr<rasterslam::bow::Vocabulary>(std::move(v));
#else
	mrpt::io::CFileGZInputStream f(path);
	return std::dynamic_pointer_cast<rasterslam::bow::Vocabulary>(
	    mrpt::serialization::archiveFrom(f).ReadObject());
#endif
}

/** Descriptors of every kind of bit pattern, the same for each input. */
const std::vector<rasterslam::bow::Descriptor>& probes()
{
	static const auto d = []
	{
		std::vector<rasterslam::bow::Descriptor> v;
		uint32_t x = 12345;
		for (int i = 0; i < 16; i++)
		{
			rasterslam::bow::Descriptor dsc{};
			for (auto& b : dsc)
			{
				x = x * 1664525u + 1013904223u;
				b = static_cast<uint8_t>(i == 0 ? 0 : i == 1 ? 0xff : x >> 24);
			}
			v.push_back(dsc);
		}
		return v;
	}();
	return d;
}
}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***)
{
	rasterslam::fuzz::registerProjectClasses();
	return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, std::size_t size)
{
	const auto path = rasterslam::fuzz::inputFile("input.vocab", data, size);
	try
	{
		const auto voc = load(path);
		if (!voc || voc->empty())
			return 0;
		(void)voc->words();
		for (const auto& d : probes())
			(void)voc->idf(voc->wordOf(d));
		rasterslam::bow::BowVector bow;
		rasterslam::bow::FeatureVector fv;
		voc->transform(probes(), bow, &fv, 2);
		(void)rasterslam::bow::Vocabulary::score(bow, bow);
	}
	catch (const std::exception&)
	{
	}
	return 0;
}
