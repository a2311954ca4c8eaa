// rasterslam-vocab: trains a bag-of-binary-words vocabulary on ORB features of elevation
// images, prints what a vocabulary file holds, and times database queries.
//   rasterslam-vocab train --images DIR [--images DIR ...] -o vocab.bin [--branching 10]
//                          [--levels 4] [--seed 1] [--features 2000]
//   rasterslam-vocab info vocab.bin
//   rasterslam-vocab bench --vocab vocab.bin [--entries 100,1000,10000] [--seed 1]
#include <mrpt/io/CFileGZInputStream.h>
#include <mrpt/io/CFileGZOutputStream.h>
#include <mrpt/serialization/CArchive.h>
#include <rasterslam/bow/vocabulary.h>
#include <rasterslam/features/orb_extractor.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <opencv2/imgcodecs.hpp>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

namespace
{
namespace fs = std::filesystem;
namespace bow = rasterslam::bow;

/** Bad command line: exit code 2 (bad input files give 1). */
struct UsageError : std::runtime_error
{
	using std::runtime_error::runtime_error;
};

const char* const kUsage =
    "usage: rasterslam-vocab train --images DIR [--images DIR ...] -o vocab.bin\n"
    "                              [--branching 10] [--levels 4] [--seed 1] [--features 2000]\n"
    "       rasterslam-vocab info vocab.bin\n"
    "       rasterslam-vocab bench --vocab vocab.bin [--entries 100,1000,10000] [--seed 1]\n";

long toInt(const std::string& opt, const std::string& v, long lo, long hi)
{
	std::size_t used = 0;
	long x = 0;
	try
	{
		x = std::stol(v, &used);
	}
	catch (const std::exception&)
	{
		used = 0;
	}
	if (used != v.size() || v.empty() || x < lo || x > hi)
		throw UsageError(opt + " needs an integer in [" + std::to_string(lo) + ", " +
		                 std::to_string(hi) + "], got '" + v + "'");
	return x;
}

/** Splits argv after the subcommand into "--key value" pairs (a key may repeat). */
std::vector<std::pair<std::string, std::string>> parse(int argc, char** argv,
                                                       const std::vector<std::string>& keys)
{
	std::vector<std::pair<std::string, std::string>> out;
	for (int i = 2; i < argc; ++i)
	{
		std::string a = argv[i], v;
		if (const auto eq = a.find('='); a.rfind("--", 0) == 0 && eq != std::string::npos)
		{
			v = a.substr(eq + 1);
			a = a.substr(0, eq);
		}
		else if (std::find(keys.begin(), keys.end(), a) != keys.end())
		{
			if (i + 1 >= argc)
				throw UsageError("option " + a + " needs a value");
			v = argv[++i];
		}
		if (std::find(keys.begin(), keys.end(), a) == keys.end())
			throw UsageError("unknown option '" + std::string(argv[i]) + "'");
		out.emplace_back(a, v);
	}
	return out;
}

int train(int argc, char** argv)
{
	std::vector<std::string> dirs;
	std::string output;
	bow::TrainParams p;
	rasterslam::features::OrbParams orb;
	for (const auto& [k, v] :
	     parse(argc, argv,
	           {"--images", "-o", "--output", "--branching", "--levels", "--seed", "--features"}))
	{
		if (k == "--images")
			dirs.push_back(v);
		else if (k == "-o" || k == "--output")
			output = v;
		else if (k == "--branching")
			p.branching = static_cast<int>(toInt(k, v, 2, 64));
		else if (k == "--levels")
			p.levels = static_cast<int>(toInt(k, v, 1, 8));
		else if (k == "--seed")
			p.seed = static_cast<uint32_t>(toInt(k, v, 0, 4294967295L));
		else if (k == "--features")
			orb.numFeatures = static_cast<int>(toInt(k, v, 1, 100000));
	}
	if (dirs.empty() || output.empty())
		throw UsageError("train needs --images DIR and -o FILE");

	std::vector<fs::path> files;
	for (const auto& d : dirs)
	{
		std::error_code ec;
		if (!fs::is_directory(d, ec))
		{
			std::cerr << "rasterslam-vocab: " << d << ": not a folder\n";
			return 1;
		}
		std::vector<fs::path> here;
		for (const auto& e : fs::directory_iterator(d))
			if (e.is_regular_file() && e.path().extension() == ".png")
				here.push_back(e.path());
		std::sort(here.begin(), here.end());  // the order fixes the result for a seed
		if (here.empty())
		{
			std::cerr << "rasterslam-vocab: " << d << ": no *.png images\n";
			return 1;
		}
		files.insert(files.end(), here.begin(), here.end());
	}

	rasterslam::features::OrbExtractor extractor(orb);
	std::vector<std::vector<bow::Descriptor>> images;
	std::size_t total = 0;
	for (const auto& f : files)
	{
		const cv::Mat img = cv::imread(f.string(), cv::IMREAD_GRAYSCALE);
		if (img.empty())
		{
			std::cerr << "rasterslam-vocab: " << f.string() << ": cannot read the image\n";
			return 1;
		}
		std::vector<cv::KeyPoint> kps;
		cv::Mat desc;
		extractor.extract(img, kps, desc);
		if (!desc.empty() && (desc.cols != 32 || desc.type() != CV_8U || !desc.isContinuous()))
		{
			std::cerr << "rasterslam-vocab: " << f.string() << ": unexpected descriptor layout\n";
			return 1;
		}
		images.push_back(bow::toDescriptors(desc.ptr<uint8_t>(), desc.empty() ? 0 : desc.rows));
		total += images.back().size();
	}
	std::cout << "images: " << images.size() << ", descriptors: " << total << "\n";
	if (total == 0)
	{
		std::cerr << "rasterslam-vocab: no ORB features in the images\n";
		return 1;
	}
	bow::Vocabulary voc;
	const auto t0 = std::chrono::steady_clock::now();
	voc.train(images, p);
	const double secs =
	    std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
	std::cout << "words: " << voc.words() << " (k = " << voc.branching() << ", L = " << voc.levels()
	          << "), trained in " << secs << " s\n";

	// A temporary name then a rename: an interrupted run never leaves a half-written file
	// under the final name.
	const std::string tmp = output + ".tmp";
	try
	{
		{
			mrpt::io::CFileGZOutputStream f;
			if (!f.open(tmp))
				throw std::runtime_error("cannot open for writing");
			mrpt::serialization::archiveFrom(f) << voc;
		}
		fs::rename(tmp, output);
	}
	catch (const std::exception& e)
	{
		std::error_code ec;
		fs::remove(tmp, ec);
		std::cerr << "rasterslam-vocab: " << output << ": " << e.what() << "\n";
		return 1;
	}
	std::cout << "wrote " << output << "\n";
	return 0;
}

/** Reads a vocabulary; errors name the file. */
bool load(const std::string& file, bow::Vocabulary& voc)
{
	try
	{
		std::error_code ec;
		if (!fs::is_regular_file(file, ec))
			throw std::runtime_error("no such file");
		mrpt::io::CFileGZInputStream f;
		if (!f.open(file))
			throw std::runtime_error("cannot open");
		const auto obj = mrpt::serialization::archiveFrom(f).ReadObject();
		const auto v = std::dynamic_pointer_cast<bow::Vocabulary>(obj);
		if (!v)
			throw std::runtime_error("not a rasterslam::bow::Vocabulary");
		voc = *v;
		return true;
	}
	catch (const std::exception& e)
	{
		std::cerr << "rasterslam-vocab: " << file << ": " << e.what() << "\n";
		return false;
	}
}

int info(int argc, char** argv)
{
	if (argc != 3)
		throw UsageError("info needs one vocabulary file");
	bow::Vocabulary voc;
	if (!load(argv[2], voc))
		return 1;
	std::size_t zero = 0;
	for (bow::WordId w = 0; w < voc.words(); ++w)
		zero += voc.idf(w) == 0;
	std::cout << "branching (k): " << voc.branching() << "\nlevels (L): " << voc.levels()
	          << "\nwords: " << voc.words() << "\ntraining images: " << voc.trainingImages()
	          << "\nwords of IDF 0: " << zero << "\n";
	return 0;
}

/** Query times on synthetic bags: Zipf-like word draws (rank r with weight 1 / r) so that
 *  the inverted lists are as uneven as with real images. */
int bench(int argc, char** argv)
{
	std::string vocFile;
	std::vector<std::size_t> sizes{100, 1000, 10000};
	uint32_t seed = 1;
	for (const auto& [k, v] : parse(argc, argv, {"--vocab", "--entries", "--seed"}))
	{
		if (k == "--vocab")
			vocFile = v;
		else if (k == "--seed")
			seed = static_cast<uint32_t>(toInt(k, v, 0, 4294967295L));
		else if (k == "--entries")
		{
			sizes.clear();
			std::size_t at = 0;
			while (at <= v.size())
			{
				const auto comma = std::min(v.find(',', at), v.size());
				sizes.push_back(toInt(k, v.substr(at, comma - at), 1, 1000000));
				at = comma + 1;
			}
		}
	}
	if (vocFile.empty())
		throw UsageError("bench needs --vocab FILE");
	bow::Vocabulary voc;
	if (!load(vocFile, voc))
		return 1;
	if (voc.words() == 0)
	{
		std::cerr << "rasterslam-vocab: " << vocFile << ": no words\n";
		return 1;
	}
	std::mt19937 rng(seed);
	std::vector<double> zipf(voc.words());
	for (std::size_t r = 0; r < zipf.size(); ++r)
		zipf[r] = 1.0 / static_cast<double>(r + 1);
	std::discrete_distribution<std::size_t> draw(zipf.begin(), zipf.end());
	std::vector<bow::WordId> perm(voc.words());  // frequent words spread over the ids
	for (std::size_t i = 0; i < perm.size(); ++i)
		perm[i] = static_cast<bow::WordId>(i);
	std::shuffle(perm.begin(), perm.end(), rng);
	const auto bag = [&]
	{
		bow::BowVector v;
		for (int i = 0; i < 2000 && v.size() < 1500; ++i)
			v[perm[draw(rng)]] += 1.0;
		double sum = 0;
		for (const auto& [w, x] : v)
			sum += x;
		for (auto& [w, x] : v)
			x /= sum;
		return v;
	};
	std::printf("%10s %8s %12s %12s\n", "entries", "words", "median_ms", "p95_ms");
	for (const std::size_t n : sizes)
	{
		bow::Database db;
		std::size_t words = 0;
		for (std::size_t i = 0; i < n; ++i)
		{
			const auto v = bag();
			words += v.size();
			db.add(v);
		}
		std::vector<double> ms;
		for (int q = 0; q < 200; ++q)
		{
			const auto v = bag();
			const auto t0 = std::chrono::steady_clock::now();
			const auto r = db.query(v, 10);
			ms.push_back(
			    std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0)
			        .count());
			if (r.size() > 10)
				return 1;  // keeps the query from being optimized away
		}
		std::sort(ms.begin(), ms.end());
		std::printf("%10zu %8zu %12.3f %12.3f\n", n, words / n, ms[ms.size() / 2],
		            ms[ms.size() * 95 / 100]);
	}
	return 0;
}
}  // namespace

int main(int argc, char** argv)
{
	try
	{
		if (argc < 2)
			throw UsageError("missing subcommand");
		const std::string cmd = argv[1];
		if (cmd == "-h" || cmd == "--help")
		{
			std::cout << kUsage;
			return 0;
		}
		if (cmd == "train")
			return train(argc, argv);
		if (cmd == "info")
			return info(argc, argv);
		if (cmd == "bench")
			return bench(argc, argv);
		throw UsageError("unknown subcommand '" + cmd + "'");
	}
	catch (const UsageError& e)
	{
		std::cerr << "rasterslam-vocab: " << e.what() << "\n" << kUsage;
		return 2;
	}
	catch (const std::exception& e)
	{
		std::cerr << "rasterslam-vocab: " << e.what() << "\n";
		return 1;
	}
}
