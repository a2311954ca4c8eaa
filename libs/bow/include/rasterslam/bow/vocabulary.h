// Bag of binary words (after Galvez-Lopez and Tardos, "Bags of Binary Words for Fast Place
// Recognition in Image Sequences", T-RO 2012, the DBoW2 paper; written here because DBoW2 is
// not packaged): a vocabulary tree over 256-bit ORB descriptors, TF-IDF weights, the
// normalized L1 score, and a database with an inverted index (entries can be removed) and a
// direct index for guided feature matching.
#pragma once

#include <mrpt/serialization/CSerializable.h>

#include <array>
#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <vector>

namespace rasterslam::bow
{
using Descriptor = std::array<uint8_t, 32>;  //!< one ORB descriptor
using WordId = uint32_t;
using NodeId = uint32_t;

/** Sparse vector of word weights, sorted by word id; L1-normalized by Vocabulary::transform. */
using BowVector = std::map<WordId, double>;
/** Direct index: for a node of the tree (a few levels above the leaves), the indices of the
 *  image's features that fall under it. Features under the same node are candidates for
 *  matching; others need not be compared. */
using FeatureVector = std::map<NodeId, std::vector<uint32_t>>;

struct TrainParams
{
	int branching = 10;      //!< k
	int levels = 4;          //!< L: up to k^L words
	int maxIterations = 10;  //!< k-medians iterations per node
	uint32_t seed = 1;
};

/** A vocabulary tree of k branches and L levels built by k-medians (the bitwise majority is
 *  the centre of a cluster of binary descriptors under the Hamming distance) with k-means++
 *  seeding. Words (leaves) carry an IDF weight log(N / n_i): N training images, n_i of them
 *  containing word i. Serialized with MRPT, versioned. */
class Vocabulary : public mrpt::serialization::CSerializable
{
	DEFINE_SERIALIZABLE(Vocabulary, rasterslam::bow)

   public:
	/** Builds the tree from the descriptors of a set of training images (one vector each).
	 *  Deterministic for a seed. Throws std::invalid_argument on bad parameters or no data. */
	void train(const std::vector<std::vector<Descriptor>>& images, const TrainParams& p);

	/** Word of a descriptor: descend the tree to a leaf, choosing the nearest child. */
	WordId wordOf(const Descriptor& d) const;
	/** TF-IDF weighted, L1-normalized bag of words of an image; with `fv`, also the direct
	 *  index at `levelsUp` levels above the leaves. */
	void transform(const std::vector<Descriptor>& features, BowVector& bow,
	               FeatureVector* fv = nullptr, int levelsUp = 2) const;

	/** DBoW2's L1 score of two L1-normalized vectors: 1 - 0.5 * |a - b|_1, in [0, 1]
	 *  (1 for identical vectors, 0 for vectors with no word in common). */
	static double score(const BowVector& a, const BowVector& b);
	/** What a place scores against itself: the score of the even descriptors' words against
	 *  the odd ones' (a query's normalizer when no neighbouring view is at hand). 0 under
	 *  `minDescriptors` (halves of a few features score by chance). */
	double selfScore(const std::vector<Descriptor>& desc, std::size_t minDescriptors = 40) const;

	std::size_t words() const { return wordNode_.size(); }
	bool empty() const { return nodes_.empty(); }
	int branching() const { return k_; }
	int levels() const { return L_; }
	double idf(WordId w) const { return w < idf_.size() ? idf_[w] : 0; }
	/** Number of images the vocabulary was trained on (N of the IDF weights). */
	std::size_t trainingImages() const { return trainingImages_; }

   private:
	struct Node
	{
		Descriptor centre{};
		std::vector<NodeId> children;
		NodeId parent = 0;
		int32_t word = -1;  //!< leaf: its word id
	};
	NodeId leafOf(const Descriptor& d) const;
	NodeId ancestor(NodeId leaf, int levelsUp) const;

	int k_ = 0, L_ = 0;
	uint32_t trainingImages_ = 0;
	std::vector<Node> nodes_;       //!< nodes_[0] is the root
	std::vector<NodeId> wordNode_;  //!< word id -> leaf node
	std::vector<double> idf_;       //!< word id -> IDF weight
};

/** An image database: an inverted index from words to (entry, weight), entries that can be
 *  added and removed, and per entry its direct index. Entry ids are never reused. */
class Database : public mrpt::serialization::CSerializable
{
	DEFINE_SERIALIZABLE(Database, rasterslam::bow)

   public:
	using EntryId = uint32_t;
	struct Result
	{
		EntryId entry = 0;
		double score = 0;
	};

	Database() = default;
	explicit Database(int directIndexLevelsUp) : levelsUp_(directIndexLevelsUp) {}

	/** Word ids this database takes: below 2^22 (a vocabulary of 10 branches and 6 levels
	 *  has 10^6 words). The index is a table by word id, 48 bytes a word up to the largest
	 *  id added. */
	static constexpr WordId kMaxWords = WordId{1} << 22;

	/** Adds an entry; throws std::invalid_argument for a word id of kMaxWords or more. */
	EntryId add(const BowVector& bow, const FeatureVector& fv = {});
	/** Removes an entry from the inverted index (e.g. a local map moved offline). Returns
	 *  false if it was not there. */
	bool remove(EntryId e);
	/** The best `maxResults` entries by score (descending; ties by entry id), among those
	 *  with at least one word in common. */
	std::vector<Result> query(const BowVector& bow, std::size_t maxResults) const;

	/** One image's words, what the image scores against itself (its normalizer), and a
	 *  weight on its scores (the first view's is not used). */
	struct View
	{
		const BowVector* words = nullptr;
		double selfScore = 0;
		double weight = 1;
	};
	/** One place seen several ways (its points rasterized at several turns) as one query:
	 *  each view's scores are put on the first view's scale (times views[0].selfScore /
	 *  its own selfScore, times its weight; a view with no normalizer counts for nothing),
	 *  an entry keeps its best, and the best `maxResults` come back as query() orders them.
	 *  With one view, query() itself. */
	std::vector<Result> queryViews(const std::vector<View>& views, std::size_t maxResults) const;

	bool contains(EntryId e) const { return entries_.count(e) != 0; }
	std::size_t size() const { return entries_.size(); }
	const FeatureVector& featureVector(EntryId e) const;
	BowVector bowVector(EntryId e) const;
	int directIndexLevelsUp() const { return levelsUp_; }

   private:
	struct Entry
	{
		/** The entry's words as a sorted array: a map node per word would cost several times
		 *  the memory for a database that lives as long as the map. */
		std::vector<std::pair<WordId, double>> bow;
		FeatureVector fv;
	};
	/** One word's postings: the entries that hold it (increasing ids) and their weights, in
	 *  two arrays so that a query reads 12 bytes a posting instead of a padded pair's 16. */
	struct Postings
	{
		std::vector<EntryId> entries;
		std::vector<double> weights;
	};
	/** Adds entry `id`'s postings for `words` (sorted, every id under kMaxWords); `id` must
	 *  be above every entry's already posted, so each word's postings stay sorted. */
	void post(EntryId id, const std::vector<std::pair<WordId, double>>& words);

	int levelsUp_ = 2;
	EntryId next_ = 0;
	std::map<EntryId, Entry> entries_;
	/** By word id: a vocabulary numbers its words from 0, so a table indexed by the word
	 *  replaces a tree search per query word. */
	std::vector<Postings> inverted_;
};

/** Converts OpenCV-style rows (N x 32 bytes, row-major) to descriptors. */
std::vector<Descriptor> toDescriptors(const uint8_t* data, std::size_t rows);

/** Writes a vocabulary file (gzip: "RSVB", version, the body's length and CRC-32, the MRPT
 *  serialization), under a temporary name then renamed. Throws naming the file. */
void saveVocabularyFile(const Vocabulary& vocabulary, const std::string& path);
/** Reads a vocabulary file, checking its checksum; files written before the checksum (the MRPT
 *  object alone) are read too. Throws std::runtime_error naming the file and what is wrong. */
std::shared_ptr<Vocabulary> loadVocabularyFile(const std::string& path);

}  // namespace rasterslam::bow
