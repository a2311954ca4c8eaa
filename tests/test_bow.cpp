// Bag of binary words: k-medians clustering of synthetic descriptors, seeding determinism,
// the L1 score, TF-IDF, the database (add, remove, query), the direct index and MRPT
// serialization (round trip, unknown version, truncated stream).
#include <mrpt/io/CFileGZInputStream.h>
#include <mrpt/io/CFileGZOutputStream.h>
#include <mrpt/io/CMemoryStream.h>
#include <mrpt/serialization/CArchive.h>
#include <rasterslam/bow/vocabulary.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <random>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

#include "test_support.h"

namespace fs = std::filesystem;
namespace test = rasterslam::test;
using namespace rasterslam::bow;

namespace
{
Descriptor randomDescriptor(std::mt19937& rng)
{
	Descriptor d;
	for (auto& b : d)
		b = static_cast<uint8_t>(rng() & 0xff);
	return d;
}

/** `proto` with `flips` random bits flipped (some may coincide). */
Descriptor noisy(const Descriptor& proto, int flips, std::mt19937& rng)
{
	Descriptor d = proto;
	for (int i = 0; i < flips; ++i)
	{
		const unsigned bit = rng() % 256;
		d[bit / 8] = static_cast<uint8_t>(d[bit / 8] ^ (1u << (bit % 8)));
	}
	return d;
}

std::vector<Descriptor> prototypes(int n, std::mt19937& rng)
{
	std::vector<Descriptor> p;
	for (int i = 0; i < n; ++i)
		p.push_back(randomDescriptor(rng));
	return p;
}

/** Images of noisy copies of prototypes: image i holds `perImage` copies of prototype
 *  (i + j) % protos for j < spread, so images differ in which prototypes they show. */
std::vector<std::vector<Descriptor>> clusteredImages(const std::vector<Descriptor>& protos,
                                                     int images, int spread, int perImage,
                                                     std::mt19937& rng)
{
	std::vector<std::vector<Descriptor>> out(images);
	for (int i = 0; i < images; ++i)
		for (int j = 0; j < spread; ++j)
			for (int c = 0; c < perImage; ++c)
				out[i].push_back(noisy(protos[(i + j) % protos.size()], 6, rng));
	return out;
}

std::vector<uint8_t> bytesOf(const mrpt::serialization::CSerializable& obj)
{
	mrpt::io::CMemoryStream buf;
	auto arch = mrpt::serialization::archiveFrom(buf);
	arch << obj;
	const auto* p = static_cast<const uint8_t*>(buf.getRawBufferData());
	return {p, p + buf.getTotalBytesCount()};
}

template <class T>
std::shared_ptr<T> roundTrip(const T& obj)
{
	mrpt::io::CMemoryStream buf;
	auto arch = mrpt::serialization::archiveFrom(buf);
	arch << obj;
	buf.Seek(0);
	return std::dynamic_pointer_cast<T>(arch.ReadObject());
}

/** Writes `obj`, sets the version byte after `name` to 9 and expects reading to throw. */
void expectUnknownVersionThrows(const mrpt::serialization::CSerializable& obj,
                                const std::string& name)
{
	mrpt::io::CMemoryStream buf;
	auto arch = mrpt::serialization::archiveFrom(buf);
	arch << obj;
	auto* bytes = static_cast<uint8_t*>(buf.getRawBufferData());
	const std::string raw(reinterpret_cast<const char*>(bytes), buf.getTotalBytesCount());
	const auto at = raw.find(name);
	ASSERT_NE(at, std::string::npos);
	ASSERT_EQ(bytes[at + name.size()], 0);  // version 0
	bytes[at + name.size()] = 9;
	buf.Seek(0);
	EXPECT_ANY_THROW(arch.ReadObject());
}

struct Fixture
{
	std::vector<Descriptor> protos;
	std::vector<std::vector<Descriptor>> images;
	Vocabulary voc;
};

Fixture makeFixture(int k = 6, int levels = 3)
{
	std::mt19937 rng(42);
	Fixture f;
	f.protos = prototypes(40, rng);
	f.images = clusteredImages(f.protos, 12, 8, 10, rng);
	TrainParams p;
	p.branching = k;
	p.levels = levels;
	p.seed = 3;
	f.voc.train(f.images, p);
	return f;
}
}  // namespace

TEST(Bow, ClustersSeparablePrototypes)
{
	std::mt19937 rng(7);
	const auto protos = prototypes(8, rng);
	std::vector<std::vector<Descriptor>> copies(8);  // one image per prototype
	for (int p = 0; p < 8; ++p)
		for (int c = 0; c < 200; ++c)
			copies[p].push_back(noisy(protos[p], 4, rng));
	Vocabulary voc;
	TrainParams params;
	params.branching = 8;
	params.levels = 1;
	voc.train(copies, params);
	EXPECT_EQ(voc.words(), 8u);
	EXPECT_EQ(voc.branching(), 8);
	EXPECT_EQ(voc.levels(), 1);
	EXPECT_EQ(voc.trainingImages(), 8u);
	std::set<WordId> words;
	for (int p = 0; p < 8; ++p)
	{
		const WordId w = voc.wordOf(protos[p]);
		words.insert(w);
		for (const auto& d : copies[p])
			ASSERT_EQ(voc.wordOf(d), w) << "prototype " << p;
	}
	EXPECT_EQ(words.size(), 8u);  // different prototypes, different words
}

TEST(Bow, SeedingIsDeterministic)
{
	std::mt19937 rng(11);
	std::vector<std::vector<Descriptor>> images(5);
	for (auto& img : images)
		for (int i = 0; i < 300; ++i)
			img.push_back(randomDescriptor(rng));
	TrainParams p;
	p.branching = 5;
	p.levels = 3;
	p.seed = 9;
	Vocabulary a, b, c;
	a.train(images, p);
	b.train(images, p);
	EXPECT_EQ(bytesOf(a), bytesOf(b));
	for (const auto& d : images[2])
		EXPECT_EQ(a.wordOf(d), b.wordOf(d));
	p.seed = 10;
	c.train(images, p);  // may differ; it must still be a valid tree
	EXPECT_GT(c.words(), 1u);
	EXPECT_LE(c.words(), 125u);
}

TEST(Bow, TrainRejectsBadInput)
{
	Vocabulary v;
	EXPECT_THROW(v.train({}, TrainParams{}), std::invalid_argument);
	EXPECT_THROW(v.train({{}, {}}, TrainParams{}), std::invalid_argument);
	TrainParams p;
	p.branching = 1;
	EXPECT_THROW(v.train({{Descriptor{}}}, p), std::invalid_argument);
	p.branching = 4;
	p.levels = 0;
	EXPECT_THROW(v.train({{Descriptor{}}}, p), std::invalid_argument);
	EXPECT_TRUE(v.empty());
	EXPECT_ANY_THROW(v.wordOf(Descriptor{}));
}

TEST(Bow, Score)
{
	const BowVector a{{1, 0.5}, {4, 0.25}, {9, 0.25}};
	const BowVector b{{2, 0.6}, {5, 0.4}};
	const BowVector c{{1, 0.25}, {4, 0.25}, {7, 0.5}};
	EXPECT_NEAR(Vocabulary::score(a, a), 1.0, 1e-12);
	EXPECT_EQ(Vocabulary::score(a, b), 0.0);
	EXPECT_EQ(Vocabulary::score(a, {}), 0.0);
	EXPECT_EQ(Vocabulary::score({}, {}), 0.0);
	// 1 - 0.5 * (0.25 + 0 + 0.25 + 0.5) = 0.5
	EXPECT_NEAR(Vocabulary::score(a, c), 0.5, 1e-12);
	EXPECT_DOUBLE_EQ(Vocabulary::score(a, c), Vocabulary::score(c, a));
	const auto f = makeFixture();
	for (std::size_t i = 0; i < f.images.size(); ++i)
		for (std::size_t j = 0; j < f.images.size(); ++j)
		{
			BowVector x, y;
			f.voc.transform(f.images[i], x);
			f.voc.transform(f.images[j], y);
			const double s = Vocabulary::score(x, y);
			EXPECT_GE(s, 0.0);
			EXPECT_LE(s, 1.0);
			EXPECT_DOUBLE_EQ(s, Vocabulary::score(y, x));
		}
}

TEST(Bow, SelfScoreOfAPlaceFromItsHalves)
{
	const auto f = makeFixture();
	// Every descriptor twice in a row: the even and the odd halves are the same features.
	std::vector<Descriptor> twice;
	for (const auto& d : f.images[0])
		twice.insert(twice.end(), {d, d});
	ASSERT_GE(twice.size(), 40u);
	EXPECT_NEAR(f.voc.selfScore(twice), 1.0, 1e-12);
	// Halves of two different places score lower.
	std::vector<Descriptor> mixed;
	for (std::size_t i = 0; i < f.images[0].size() && i < f.images[6].size(); i++)
		mixed.insert(mixed.end(), {f.images[0][i], f.images[6][i]});
	ASSERT_GE(mixed.size(), 40u);
	EXPECT_LT(f.voc.selfScore(mixed), 0.9);
	// Too few features to judge: no normalizer.
	const std::vector<Descriptor> few(twice.begin(), twice.begin() + 38);
	EXPECT_EQ(f.voc.selfScore(few), 0.0);
	EXPECT_NEAR(f.voc.selfScore(few, 2), 1.0, 1e-12);
}

TEST(Bow, TransformIsL1Normalized)
{
	const auto f = makeFixture();
	for (const auto& img : f.images)
	{
		BowVector v;
		f.voc.transform(img, v);
		ASSERT_FALSE(v.empty());
		double sum = 0;
		for (const auto& [w, x] : v)
		{
			EXPECT_GT(x, 0.0);
			EXPECT_LT(w, f.voc.words());
			sum += x;
		}
		EXPECT_NEAR(sum, 1.0, 1e-12);
	}
	BowVector none{{3, 1.0}};
	f.voc.transform({}, none);
	EXPECT_TRUE(none.empty());
}

TEST(Bow, IdfFavoursRareWords)
{
	std::mt19937 rng(5);
	const auto protos = prototypes(8, rng);
	// Prototype 0 in every image, prototype 1 in image 0 only, the others in a few; about
	// 200 copies of each overall, so that the clusters are found alike.
	std::vector<std::vector<Descriptor>> images(10);
	for (int i = 0; i < 10; ++i)
	{
		for (int c = 0; c < 20; ++c)
			images[i].push_back(noisy(protos[0], 4, rng));
		for (int p = 2; p < 8; ++p)
			if ((i + p) % 3 == 0)
				for (int c = 0; c < 60; ++c)
					images[i].push_back(noisy(protos[p], 4, rng));
	}
	for (int c = 0; c < 200; ++c)
		images[0].push_back(noisy(protos[1], 4, rng));
	Vocabulary voc;
	TrainParams p;
	p.branching = 8;
	p.levels = 1;
	voc.train(images, p);
	const WordId common = voc.wordOf(protos[0]), rare = voc.wordOf(protos[1]);
	ASSERT_NE(common, rare);
	EXPECT_EQ(voc.idf(common), 0.0);
	EXPECT_NEAR(voc.idf(rare), std::log(10.0), 1e-12);
	EXPECT_LT(voc.idf(common), voc.idf(voc.wordOf(protos[2])));
	// Features of the word seen everywhere contribute nothing.
	BowVector v;
	voc.transform({protos[0], protos[0]}, v);
	EXPECT_TRUE(v.empty());
	voc.transform({protos[0], protos[1]}, v);
	ASSERT_EQ(v.size(), 1u);
	EXPECT_EQ(v.begin()->first, rare);
	EXPECT_DOUBLE_EQ(v.begin()->second, 1.0);
}

TEST(Bow, DatabaseAddRemoveQuery)
{
	const auto f = makeFixture();
	Database db(1);
	std::vector<BowVector> bows(f.images.size());
	for (std::size_t i = 0; i < f.images.size(); ++i)
	{
		f.voc.transform(f.images[i], bows[i]);
		EXPECT_EQ(db.add(bows[i]), i);
	}
	EXPECT_EQ(db.size(), f.images.size());
	for (std::size_t i = 0; i < f.images.size(); ++i)
	{
		const auto r = db.query(bows[i], 5);
		ASSERT_FALSE(r.empty());
		EXPECT_EQ(r.front().entry, i);
		EXPECT_NEAR(r.front().score, 1.0, 1e-9);
		EXPECT_LE(r.size(), 5u);
		for (std::size_t j = 1; j < r.size(); ++j)
		{
			EXPECT_TRUE(r[j - 1].score > r[j].score ||
			            (r[j - 1].score == r[j].score && r[j - 1].entry < r[j].entry));
			EXPECT_NEAR(r[j].score, Vocabulary::score(bows[i], bows[r[j].entry]), 1e-9);
		}
	}
	EXPECT_TRUE(db.remove(3));
	EXPECT_FALSE(db.remove(3));
	EXPECT_FALSE(db.contains(3));
	EXPECT_EQ(db.size(), f.images.size() - 1);
	EXPECT_THROW(db.bowVector(3), std::out_of_range);
	// The inverted index no longer holds entry 3: its own vector finds the others only.
	const auto r = db.query(bows[3], 100);
	EXPECT_FALSE(r.empty());
	for (const auto& x : r)
		EXPECT_NE(x.entry, 3u);
	// Ids are not reused.
	const auto id = db.add(bows[3]);
	EXPECT_EQ(id, f.images.size());
	EXPECT_EQ(db.query(bows[3], 1).front().entry, id);
	// No word in common, nothing found.
	EXPECT_TRUE(db.query(BowVector{{999999, 1.0}}, 10).empty());
	EXPECT_TRUE(db.query(bows[0], 0).empty());
}

// The query against every entry scored one by one (Vocabulary::score), on bags of random
// words and weights: while ids are dense (scores in an array) and after most entries are
// removed (ids much sparser than the entries: scores in a hash map). Each query's results are
// the best by (score, id) of every entry sharing a word, with its score.
TEST(Bow, DatabaseQueryIsEveryEntryScoredOneByOneDenseOrSparse)
{
	std::mt19937 rng(17);
	std::uniform_int_distribution<WordId> word(0, 2999);
	std::uniform_real_distribution<double> weight(0.01, 1.0);
	const auto bag = [&](int words)
	{
		BowVector v;
		while (static_cast<int>(v.size()) < words)
			v[word(rng)] = weight(rng);
		double sum = 0;
		for (const auto& [w, x] : v)
			sum += x;
		for (auto& [w, x] : v)
			x /= sum;
		return v;
	};
	Database db;
	std::map<Database::EntryId, BowVector> live;
	const auto expectPlainScores = [&](const char* phase)
	{
		SCOPED_TRACE(phase);
		for (int q = 0; q < 20; ++q)
		{
			const BowVector query = bag(150);
			std::vector<Database::Result> plain;
			for (const auto& [id, v] : live)
			{
				bool common = false;
				for (const auto& [w, x] : query)
					common = common || v.count(w) != 0;
				if (common)
					plain.push_back({id, Vocabulary::score(query, v)});
			}
			std::sort(plain.begin(), plain.end(),
			          [](const auto& a, const auto& b)
			          { return a.score != b.score ? a.score > b.score : a.entry < b.entry; });
			ASSERT_GT(plain.size(), 10u);
			for (const std::size_t k : {std::size_t{10}, plain.size() + 5})
			{
				// Scores summed in another order may differ in the last bits, and then break
				// a tie the other way: each result is checked against its own entry's score
				// and the ranks' scores against the plain ranking's.
				const auto r = db.query(query, k);
				ASSERT_EQ(r.size(), std::min(k, plain.size()));
				std::set<Database::EntryId> returned;
				for (std::size_t i = 0; i < r.size(); ++i)
				{
					ASSERT_EQ(live.count(r[i].entry), 1u) << "rank " << i;
					EXPECT_TRUE(returned.insert(r[i].entry).second) << "rank " << i;
					EXPECT_NEAR(r[i].score, Vocabulary::score(query, live.at(r[i].entry)), 1e-12)
					    << "rank " << i;
					EXPECT_NEAR(r[i].score, plain[i].score, 1e-12) << "rank " << i;
					if (i > 0)
						EXPECT_TRUE(r[i - 1].score > r[i].score ||
						            (r[i - 1].score == r[i].score && r[i - 1].entry < r[i].entry))
						    << "rank " << i;
				}
				// Nothing left out scores above the last one returned.
				for (const auto& p : plain)
					if (!returned.count(p.entry))
						EXPECT_LE(p.score, r.back().score + 1e-12) << "entry " << p.entry;
			}
		}
	};
	for (int i = 0; i < 5000; ++i)
	{
		auto v = bag(i < 300 ? 150 : 5);
		live.emplace(db.add(v), std::move(v));
	}
	expectPlainScores("dense ids");
	// Keep one entry in 50: 100 live entries among 5,000 ids.
	for (auto it = live.begin(); it != live.end();)
		if (it->first % 50 != 7)
		{
			EXPECT_TRUE(db.remove(it->first));
			it = live.erase(it);
		}
		else
			++it;
	ASSERT_EQ(db.size(), 100u);
	expectPlainScores("sparse ids");
	// The word table has a bound: a word beyond it is refused with its id, nothing added.
	EXPECT_NO_THROW(db.add(BowVector{{65535, 1.0}}));
	try
	{
		db.add(BowVector{{1, 0.5}, {Database::kMaxWords, 0.5}});
		ADD_FAILURE() << "a word id of kMaxWords was taken";
	}
	catch (const std::invalid_argument& e)
	{
		EXPECT_NE(std::string(e.what()).find(std::to_string(Database::kMaxWords)),
		          std::string::npos)
		    << e.what();
	}
	EXPECT_EQ(db.size(), 101u);
}

TEST(Bow, QueryViewsKeepEachEntrysBestOnTheFirstViewsScale)
{
	const auto f = makeFixture();
	ASSERT_GE(f.images.size(), 4u);
	Database db;
	std::vector<BowVector> bows(f.images.size());
	for (std::size_t i = 0; i < f.images.size(); ++i)
	{
		f.voc.transform(f.images[i], bows[i]);
		db.add(bows[i]);
	}
	// One view: query() itself.
	const auto one = db.queryViews({{&bows[0], 0.5}}, 3);
	const auto plain = db.query(bows[0], 3);
	ASSERT_EQ(one.size(), plain.size());
	for (std::size_t i = 0; i < one.size(); ++i)
	{
		EXPECT_EQ(one[i].entry, plain[i].entry);
		EXPECT_EQ(one[i].score, plain[i].score);
	}
	// Two views of "one place": the second's scores count at 0.5 / 0.25 = twice, so its own
	// entry (score 1 against itself) comes first at 2, and the first view's own entry keeps
	// its 1 where the second view scores it lower.
	const auto two = db.queryViews({{&bows[0], 0.5}, {&bows[2], 0.25}}, 100);
	ASSERT_GE(two.size(), 2u);
	EXPECT_EQ(two[0].entry, 2u);
	EXPECT_NEAR(two[0].score, 2.0, 1e-9);
	for (std::size_t i = 0; i < two.size(); ++i)
	{
		const auto e = two[i].entry;
		EXPECT_NEAR(
		    two[i].score,
		    std::max(Vocabulary::score(bows[0], bows[e]), 2 * Vocabulary::score(bows[2], bows[e])),
		    1e-9);
		if (i > 0)
		{
			EXPECT_TRUE(two[i - 1].score > two[i].score ||
			            (two[i - 1].score == two[i].score && two[i - 1].entry < e));
		}
		for (std::size_t j = 0; j < i; ++j)
			EXPECT_NE(two[j].entry, e);  // an entry once, at its best
	}
	// A weight scales a view's scores: at 0.25 the second view's own entry scores 0.5.
	const auto weighed = db.queryViews({{&bows[0], 0.5}, {&bows[2], 0.25, 0.25}}, 100);
	ASSERT_FALSE(weighed.empty());
	EXPECT_EQ(weighed.front().entry, 0u);
	for (const auto& x : weighed)
		EXPECT_NEAR(x.score,
		            std::max(Vocabulary::score(bows[0], bows[x.entry]),
		                     0.5 * Vocabulary::score(bows[2], bows[x.entry])),
		            1e-9);
	// At most maxResults; a view with no normalizer counts for nothing.
	EXPECT_LE(db.queryViews({{&bows[0], 0.5}, {&bows[2], 0.25}}, 2).size(), 2u);
	const auto none = db.queryViews({{&bows[0], 0.5}, {&bows[2], 0.0}}, 100);
	ASSERT_FALSE(none.empty());
	EXPECT_EQ(none.front().entry, 0u);
	EXPECT_TRUE(db.queryViews({}, 5).empty());
}

TEST(Bow, DirectIndex)
{
	const auto f = makeFixture(4, 3);
	const auto& img = f.images[0];
	for (const int up : {0, 1, 2, 99})
	{
		BowVector v;
		FeatureVector fv;
		f.voc.transform(img, v, &fv, up);
		std::vector<int> seen(img.size(), 0);
		for (const auto& [node, features] : fv)
		{
			EXPECT_NE(node, 0u);  // never the root
			for (const uint32_t i : features)
			{
				ASSERT_LT(i, img.size());
				++seen[i];
			}
			if (up == 0)  // at the leaves a node is a word
			{
				for (const uint32_t i : features)
				{
					EXPECT_EQ(f.voc.wordOf(img[i]), f.voc.wordOf(img[features[0]]));
				}
			}
		}
		for (const int s : seen)
		{
			EXPECT_EQ(s, 1);
		}
		if (up == 99)
		{
			EXPECT_LE(fv.size(), 4u);  // clamped at the children of the root
		}
	}
	// Equal descriptors share their node whatever the level.
	BowVector v;
	FeatureVector fv;
	f.voc.transform({img[5], img[7], img[5]}, v, &fv, 1);
	bool together = false;
	for (const auto& [node, features] : fv)
		if (!features.empty() && features.front() == 0)
			together = features.back() == 2;
	EXPECT_TRUE(together);
}

TEST(Bow, VocabularySerialization)
{
	const auto f = makeFixture();
	const auto back = roundTrip(f.voc);
	ASSERT_TRUE(back);
	EXPECT_EQ(back->words(), f.voc.words());
	EXPECT_EQ(back->branching(), f.voc.branching());
	EXPECT_EQ(back->levels(), f.voc.levels());
	EXPECT_EQ(back->trainingImages(), f.voc.trainingImages());
	for (WordId w = 0; w < f.voc.words(); ++w)
		EXPECT_EQ(back->idf(w), f.voc.idf(w));
	for (const auto& img : f.images)
		for (const auto& d : img)
			ASSERT_EQ(back->wordOf(d), f.voc.wordOf(d));
	EXPECT_EQ(bytesOf(*back), bytesOf(f.voc));
	expectUnknownVersionThrows(f.voc, "rasterslam::bow::Vocabulary");

	// A truncated stream is refused.
	auto bytes = bytesOf(f.voc);
	bytes.resize(bytes.size() / 2);
	mrpt::io::CMemoryStream cut;
	cut.Write(bytes.data(), bytes.size());
	cut.Seek(0);
	auto arch = mrpt::serialization::archiveFrom(cut);
	EXPECT_ANY_THROW(arch.ReadObject());

	// An empty vocabulary goes through too.
	const auto empty = roundTrip(Vocabulary{});
	ASSERT_TRUE(empty);
	EXPECT_TRUE(empty->empty());
}

TEST(Bow, VocabularyFileHasAChecksumAndOlderFilesStillLoad)
{
	const auto f = makeFixture();
	const test::ScopedTempDir dir("bow-file");
	const auto path = (dir / "v.vocab").string();
	saveVocabularyFile(f.voc, path);
	const auto back = loadVocabularyFile(path);
	ASSERT_TRUE(back);
	EXPECT_EQ(bytesOf(*back), bytesOf(f.voc));
	// Nothing but the file is left (no temporary).
	EXPECT_EQ(std::distance(fs::directory_iterator(dir.path()), fs::directory_iterator()), 1);

	// The file uncompressed: "RSVB", version (1), body length (8), CRC-32 (4), body.
	std::vector<uint8_t> raw;
	{
		mrpt::io::CFileGZInputStream in(path);
		uint8_t buf[4096];
		for (std::size_t n; (n = in.Read(buf, sizeof buf)) > 0;)
			raw.insert(raw.end(), buf, buf + n);
	}
	ASSERT_GT(raw.size(), 17u);
	EXPECT_EQ(std::string(raw.begin(), raw.begin() + 4), "RSVB");
	const auto write = [&](const std::vector<uint8_t>& bytes)
	{
		mrpt::io::CFileGZOutputStream out(path);
		out.Write(bytes.data(), bytes.size());
	};
	const auto errorOf = [&]() -> std::string
	{
		try
		{
			loadVocabularyFile(path);
		}
		catch (const std::runtime_error& e)
		{
			return e.what();
		}
		return "";
	};
	std::mt19937 rng(8);
	std::uniform_int_distribution<std::size_t> pos(17, raw.size() - 1);
	for (int i = 0; i < 20; i++)
	{
		auto bad = raw;
		bad[pos(rng)] ^= static_cast<uint8_t>(1u << (i % 8));
		write(bad);
		EXPECT_EQ(errorOf(), "vocabulary '" + path + "': checksum mismatch (the file is damaged)");
	}
	write(std::vector<uint8_t>(raw.begin(), raw.end() - 1));
	EXPECT_NE(errorOf().find("truncated"), std::string::npos) << errorOf();
	auto huge = raw;
	const uint64_t big = uint64_t(1) << 40;
	std::memcpy(huge.data() + 5, &big, 8);
	write(huge);
	EXPECT_NE(errorOf().find("damaged header"), std::string::npos) << errorOf();

	// A file of the older format (the MRPT object alone) still loads.
	{
		mrpt::io::CFileGZOutputStream out(path);
		mrpt::serialization::archiveFrom(out) << f.voc;
	}
	const auto old = loadVocabularyFile(path);
	ASSERT_TRUE(old);
	EXPECT_EQ(bytesOf(*old), bytesOf(f.voc));
	// Not a vocabulary, and no file: named.
	std::ofstream(path) << "text";
	EXPECT_NE(errorOf().find("vocabulary '" + path + "': "), std::string::npos) << errorOf();
	fs::remove(path);
	EXPECT_EQ(errorOf(), "vocabulary '" + path + "': no such file");
}

TEST(Bow, DatabaseSerialization)
{
	const auto f = makeFixture();
	Database db(2);
	std::vector<BowVector> bows(f.images.size());
	for (std::size_t i = 0; i < f.images.size(); ++i)
	{
		FeatureVector fv;
		f.voc.transform(f.images[i], bows[i], &fv, 2);
		db.add(bows[i], fv);
	}
	db.remove(4);
	const auto back = roundTrip(db);
	ASSERT_TRUE(back);
	EXPECT_EQ(back->size(), db.size());
	EXPECT_EQ(back->directIndexLevelsUp(), 2);
	EXPECT_FALSE(back->contains(4));
	for (std::size_t i = 0; i < f.images.size(); ++i)
	{
		const auto a = db.query(bows[i], 6), b = back->query(bows[i], 6);
		ASSERT_EQ(a.size(), b.size());
		for (std::size_t j = 0; j < a.size(); ++j)
		{
			EXPECT_EQ(a[j].entry, b[j].entry);
			EXPECT_EQ(a[j].score, b[j].score);
		}
		if (i != 4)
		{
			EXPECT_EQ(back->featureVector(i), db.featureVector(i));
			EXPECT_EQ(back->bowVector(i), db.bowVector(i));
		}
	}
	Database copy = db;
	EXPECT_EQ(back->add(bows[0]), copy.add(bows[0]));  // ids carry on, not reused
	expectUnknownVersionThrows(db, "rasterslam::bow::Database");
}
