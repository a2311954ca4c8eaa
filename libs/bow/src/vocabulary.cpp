// Vocabulary tree: hierarchical k-medians training, IDF weights, word look-up, TF-IDF
// transform with the direct index, the L1 score, and MRPT serialization.
#include <mrpt/core/exceptions.h>
#include <mrpt/core/initializer.h>
#include <mrpt/serialization/CArchive.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <functional>
#include <limits>
#include <random>
#include <set>
#include <stdexcept>
#include <string>

#include "kmedians.h"

using namespace rasterslam::bow;

IMPLEMENTS_SERIALIZABLE(Vocabulary, mrpt::serialization::CSerializable, rasterslam::bow)
IMPLEMENTS_SERIALIZABLE(Database, mrpt::serialization::CSerializable, rasterslam::bow)

// Registered from an ordinary static object of this file, after the runtime ids above (see
// rasterslam/map/registration.h: MRPT_INITIALIZER's order is unspecified, clang runs it first).
namespace
{
struct RegisterBowClasses
{
	RegisterBowClasses()
	{
		mrpt::rtti::registerClass(CLASS_ID(rasterslam::bow::Vocabulary));
		mrpt::rtti::registerClass(CLASS_ID(rasterslam::bow::Database));
	}
} registerBowClasses;
}  // namespace

void Vocabulary::train(const std::vector<std::vector<Descriptor>>& images, const TrainParams& p)
{
	if (p.branching < 2 || p.levels < 1 || p.maxIterations < 1)
		throw std::invalid_argument(
		    "Vocabulary::train: needs branching >= 2, levels >= 1 and maxIterations >= 1");
	std::vector<Descriptor> all;
	for (const auto& img : images)
		all.insert(all.end(), img.begin(), img.end());
	if (all.empty())
		throw std::invalid_argument("Vocabulary::train: no training descriptors");
	if (all.size() > std::numeric_limits<uint32_t>::max())
		throw std::invalid_argument("Vocabulary::train: too many training descriptors");

	k_ = p.branching;
	L_ = p.levels;
	trainingImages_ = static_cast<uint32_t>(images.size());
	nodes_.assign(1, Node{});
	std::mt19937 rng(p.seed);

	// Depth first, one generator: the tree depends on the seed only. A node becomes a leaf at
	// depth L or when its descriptors are all equal; with at most k descriptors (DBoW2's
	// trivial case) each distinct descriptor becomes a leaf child, since clustering would only
	// reproduce them.
	const std::function<void(NodeId, std::vector<uint32_t>&, int)> split =
	    [&](NodeId node, std::vector<uint32_t>& members, int depth)
	{
		if (depth >= L_ || members.size() <= 1)
			return;
		std::vector<Descriptor> centres;
		std::vector<std::vector<uint32_t>> groups;
		if (members.size() <= static_cast<std::size_t>(k_))
		{
			for (const uint32_t m : members)
			{
				const auto c = std::find(centres.begin(), centres.end(), all[m]);
				if (c == centres.end())
				{
					centres.push_back(all[m]);
					groups.push_back({m});
				}
				else
					groups[c - centres.begin()].push_back(m);
			}
		}
		else
			detail::kMedians(all, members, k_, p.maxIterations, rng, centres, groups);
		if (centres.size() <= 1)
			return;  // all equal: splitting would add a chain of single children
		members.clear();
		members.shrink_to_fit();  // the children hold them now; keeps peak memory down
		const NodeId firstChild = static_cast<NodeId>(nodes_.size());
		for (std::size_t c = 0; c < centres.size(); ++c)
		{
			Node child;
			child.centre = centres[c];
			child.parent = node;
			nodes_.push_back(child);
			nodes_[node].children.push_back(firstChild + static_cast<NodeId>(c));
		}
		for (std::size_t c = 0; c < centres.size(); ++c)
			split(firstChild + static_cast<NodeId>(c), groups[c], depth + 1);
	};
	std::vector<uint32_t> members(all.size());
	for (std::size_t i = 0; i < all.size(); ++i)
		members[i] = static_cast<uint32_t>(i);
	split(0, members, 0);

	// Words are the leaves in the order their nodes were created.
	wordNode_.clear();
	for (NodeId n = 0; n < nodes_.size(); ++n)
		if (nodes_[n].children.empty())
		{
			nodes_[n].word = static_cast<int32_t>(wordNode_.size());
			wordNode_.push_back(n);
		}

	// IDF from the words the images get through the tree (the look-up descends greedily, so
	// a training descriptor need not reach the leaf it was clustered into). A word no image
	// reaches gets log(N), as rare as a word seen once: a weight of 0 would make its features
	// count for nothing in every later image.
	std::vector<uint32_t> seenIn(wordNode_.size(), 0);
	std::vector<uint32_t> lastImage(wordNode_.size(), std::numeric_limits<uint32_t>::max());
	for (uint32_t i = 0; i < images.size(); ++i)
		for (const Descriptor& d : images[i])
		{
			const WordId w = wordOf(d);
			if (lastImage[w] != i)
			{
				lastImage[w] = i;
				++seenIn[w];
			}
		}
	const double n = static_cast<double>(images.size());
	idf_.resize(wordNode_.size());
	for (std::size_t w = 0; w < idf_.size(); ++w)
		idf_[w] = std::log(n / std::max<double>(seenIn[w], 1));
}

NodeId Vocabulary::leafOf(const Descriptor& d) const
{
	if (nodes_.empty())
		throw std::logic_error("Vocabulary: empty (not trained or loaded)");
	NodeId node = 0;
	while (!nodes_[node].children.empty())
	{
		NodeId best = nodes_[node].children.front();
		int bestDist = std::numeric_limits<int>::max();
		for (const NodeId c : nodes_[node].children)
		{
			const int dist = detail::hamming(d, nodes_[c].centre);
			if (dist < bestDist)
			{
				bestDist = dist;
				best = c;
			}
		}
		node = best;
	}
	return node;
}

WordId Vocabulary::wordOf(const Descriptor& d) const
{
	return static_cast<WordId>(nodes_[leafOf(d)].word);
}

NodeId Vocabulary::ancestor(NodeId leaf, int levelsUp) const
{
	// Never above the children of the root: the root would put every feature in one group.
	NodeId node = leaf;
	for (int i = 0; i < levelsUp && node != 0 && nodes_[node].parent != 0; ++i)
		node = nodes_[node].parent;
	return node;
}

void Vocabulary::transform(const std::vector<Descriptor>& features, BowVector& bow,
                           FeatureVector* fv, int levelsUp) const
{
	bow.clear();
	if (fv)
		fv->clear();
	if (features.empty())
		return;
	const double tf = 1.0 / static_cast<double>(features.size());
	for (uint32_t i = 0; i < features.size(); ++i)
	{
		const NodeId leaf = leafOf(features[i]);
		const WordId w = static_cast<WordId>(nodes_[leaf].word);
		// Words of IDF 0 (in every training image) tell images apart no better than nothing.
		if (idf_[w] > 0)
			bow[w] += tf * idf_[w];
		if (fv)
			(*fv)[ancestor(leaf, levelsUp)].push_back(i);
	}
	double sum = 0;
	for (const auto& [w, v] : bow)
		sum += std::abs(v);
	if (sum > 0)
		for (auto& [w, v] : bow)
			v /= sum;
}

double Vocabulary::score(const BowVector& a, const BowVector& b)
{
	if (a.empty() || b.empty())
		return 0;
	// Only common words change |a - b|_1 from |a|_1 + |b|_1 = 2: sum there
	// |a_i| + |b_i| - |a_i - b_i|, half of which is the score.
	double s = 0;
	auto ia = a.begin();
	auto ib = b.begin();
	while (ia != a.end() && ib != b.end())
	{
		if (ia->first < ib->first)
			++ia;
		else if (ib->first < ia->first)
			++ib;
		else
		{
			s += std::abs(ia->second) + std::abs(ib->second) - std::abs(ia->second - ib->second);
			++ia;
			++ib;
		}
	}
	return std::clamp(0.5 * s, 0.0, 1.0);  // rounding may leave 1 + 1e-16
}

uint8_t Vocabulary::serializeGetVersion() const
{
	return 0;
}

void Vocabulary::serializeTo(mrpt::serialization::CArchive& out) const
{
	out << static_cast<int32_t>(k_) << static_cast<int32_t>(L_) << trainingImages_
	    << static_cast<uint32_t>(nodes_.size());
	for (const Node& n : nodes_)
	{
		out.WriteBuffer(n.centre.data(), n.centre.size());
		out << n.parent << n.word << static_cast<uint32_t>(n.children.size());
		for (const NodeId c : n.children)
			out << c;
	}
	out << static_cast<uint32_t>(idf_.size());
	for (const double v : idf_)
		out << v;
}

void Vocabulary::serializeFrom(mrpt::serialization::CArchive& in, uint8_t version)
{
	const auto bad = [](const std::string& why)
	{ THROW_EXCEPTION("rasterslam::bow::Vocabulary: inconsistent stream: " + why); };
	int32_t k = 0, L = 0;
	uint32_t images = 0, count = 0, words = 0;
	std::vector<Node> nodes;
	std::vector<double> idf;
	switch (version)
	{
		case 0:
		{
			in >> k >> L >> images >> count;
			// Read node by node: a corrupt count then ends in a read error, not a huge
			// allocation.
			for (uint32_t i = 0; i < count; ++i)
			{
				Node n;
				if (in.ReadBuffer(n.centre.data(), n.centre.size()) != n.centre.size())
					bad("truncated node");
				uint32_t children = 0;
				in >> n.parent >> n.word >> children;
				if (children > count)
					bad("too many children");
				for (uint32_t c = 0; c < children; ++c)
				{
					NodeId id = 0;
					in >> id;
					n.children.push_back(id);
				}
				nodes.push_back(std::move(n));
			}
			in >> words;
			if (words > count)
				bad("more weights than nodes");
			idf.resize(words);
			for (double& v : idf)
				in >> v;
			break;
		}
		default:
			MRPT_THROW_UNKNOWN_SERIALIZATION_VERSION(version);
	}
	if (count == 0)
	{
		if (words != 0)
			bad("weights without a tree");
	}
	else if (k < 2 || L < 1)
		bad("branching or levels out of range");
	// Children come after their parent (depth-first creation), which rules out cycles; each
	// node but the root has one parent and lies at most L levels deep.
	std::vector<int> depth(count, -1);
	std::vector<NodeId> wordNode(words, 0);
	std::vector<bool> wordSeen(words, false);
	if (count > 0)
		depth[0] = 0;
	for (NodeId n = 0; n < count; ++n)
	{
		if (n > 0 && depth[n] < 0)
			bad("node without a parent");
		const Node& node = nodes[n];
		if (node.children.size() > static_cast<std::size_t>(k))
			bad("more than k children");
		for (const NodeId c : node.children)
		{
			if (c <= n || c >= count || depth[c] >= 0 || nodes[c].parent != n)
				bad("child id out of range or parent mismatch");
			depth[c] = depth[n] + 1;
			if (depth[c] > L)
				bad("deeper than L levels");
		}
		const bool leaf = node.children.empty();
		if (leaf != (node.word >= 0) || (leaf && static_cast<uint32_t>(node.word) >= words))
			bad("word ids do not match the leaves");
		if (leaf)
		{
			if (wordSeen[node.word])
				bad("word id used twice");
			wordSeen[node.word] = true;
			wordNode[node.word] = n;
		}
	}
	if (std::find(wordSeen.begin(), wordSeen.end(), false) != wordSeen.end())
		bad("a word without a leaf");
	for (const double v : idf)
		if (!std::isfinite(v) || v < 0)
			bad("IDF weight not finite or negative");
	k_ = count ? k : 0;
	L_ = count ? L : 0;
	trainingImages_ = images;
	nodes_ = std::move(nodes);
	wordNode_ = std::move(wordNode);
	idf_ = std::move(idf);
}

static_assert(sizeof(Descriptor) == 32, "descriptors are copied as rows of 32 bytes");

std::vector<Descriptor> rasterslam::bow::toDescriptors(const uint8_t* data, std::size_t rows)
{
	std::vector<Descriptor> out(rows);
	if (rows > 0)
		std::memcpy(out.data(), data, rows * sizeof(Descriptor));
	return out;
}

double rasterslam::bow::Vocabulary::selfScore(const std::vector<Descriptor>& desc,
                                              std::size_t minDescriptors) const
{
	if (desc.size() < minDescriptors)
		return 0;
	std::vector<Descriptor> even, odd;
	for (std::size_t i = 0; i < desc.size(); i++)
		(i % 2 ? odd : even).push_back(desc[i]);
	BowVector be, bo;
	transform(even, be);
	transform(odd, bo);
	return score(be, bo);
}
