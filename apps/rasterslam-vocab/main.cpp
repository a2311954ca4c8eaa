// rasterslam-vocab: trains a bag-of-binary-words vocabulary on ORB features of elevation
// images, prints what a vocabulary file holds, and times database queries (rasterslam-vocab
// --help).
#include <mrpt/io/CFileGZInputStream.h>
#include <mrpt/io/CFileGZOutputStream.h>
#include <mrpt/serialization/CArchive.h>
#include <rasterslam/bow/vocabulary.h>
#include <rasterslam/cli/app.h>
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

namespace cli = rasterslam::cli;

struct TrainArgs
{
	std::vector<std::string> dirs;
	std::string output;
	bow::TrainParams params;
	rasterslam::features::OrbParams orb;
};

struct BenchArgs
{
	std::string vocab;
	std::vector<std::size_t> sizes{100, 1000, 10000};
	uint32_t seed = 1;
};

int train(const TrainArgs& args)
{
	const auto& p = args.params;
	const auto& orb = args.orb;
	const auto& output = args.output;
	std::vector<fs::path> files;
	for (const auto& d : args.dirs)
	{
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

	// Written with its checksum, under a temporary name then renamed: an interrupted run never
	// leaves a half-written file under the final name.
	try
	{
		bow::saveVocabularyFile(voc, output);
	}
	catch (const std::exception& e)
	{
		std::cerr << "rasterslam-vocab: " << e.what() << "\n";
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
		voc = *bow::loadVocabularyFile(file);
		return true;
	}
	catch (const std::exception& e)
	{
		std::cerr << "rasterslam-vocab: " << e.what() << "\n";
		return false;
	}
}

int info(const std::string& file)
{
	bow::Vocabulary voc;
	if (!load(file, voc))
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
int bench(const BenchArgs& args)
{
	const std::string& vocFile = args.vocab;
	bow::Vocabulary voc;
	if (!load(vocFile, voc))
		return 1;
	if (voc.words() == 0)
	{
		std::cerr << "rasterslam-vocab: " << vocFile << ": no words\n";
		return 1;
	}
	std::mt19937 rng(args.seed);
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
	for (const std::size_t n : args.sizes)
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
	CLI::App app(
	    "rasterslam-vocab: trains a bag-of-binary-words vocabulary on ORB features of elevation "
	    "images, prints what a vocabulary file holds, and times database queries.",
	    "rasterslam-vocab");
	cli::configure(app);
	app.footer(
	    "usage:\n"
	    "rasterslam-vocab train --images DIR [--images DIR ...] -o vocab.bin [--branching 10] "
	    "[--levels 4] [--seed 1] [--features 2000]\n"
	    "rasterslam-vocab info vocab.bin\n"
	    "rasterslam-vocab convert old.vocab -o new.vocab\n"
	    "rasterslam-vocab bench --vocab vocab.bin [--entries 100,1000,10000] [--seed 1]\n"
	    "(rasterslam-vocab SUBCOMMAND --help for its options)\n\n" +
	    std::string(cli::exitCodesFooter()));
	app.require_subcommand(1);

	TrainArgs t;
	CLI::App* trainCmd =
	    cli::subcommand(app, "train", "train a vocabulary on the *.png images of folders");
	trainCmd
	    ->add_option("--images", t.dirs,
	                 "folder of *.png elevation images (repeat for more folders; the images are "
	                 "taken in name order)")
	    ->required()
	    ->check(CLI::ExistingDirectory.description(""))
	    ->type_name("DIR")
	    ->expected(1)
	    ->multi_option_policy(CLI::MultiOptionPolicy::TakeAll);
	trainCmd->add_option("-o,--output", t.output, "vocabulary file to write")
	    ->required()
	    ->type_name("FILE");
	trainCmd
	    ->add_option("--branching", t.params.branching, "branches a node, k (2..64; default 10)")
	    ->check(CLI::Range(2, 64).description(""))
	    ->type_name("K");
	trainCmd->add_option("--levels", t.params.levels, "levels of the tree, L (1..8; default 4)")
	    ->check(CLI::Range(1, 8).description(""))
	    ->type_name("L");
	trainCmd
	    ->add_option(
	        "--seed", t.params.seed,
	        "seed of the k-means++ seeding: a seed and the images fix the result (default 1)")
	    ->type_name("S");
	trainCmd
	    ->add_option("--features", t.orb.numFeatures,
	                 "ORB features an image (1..100000; default 2000)")
	    ->check(CLI::Range(1, 100000).description(""))
	    ->type_name("N");

	std::string infoFile;
	CLI::App* infoCmd = cli::subcommand(app, "info", "print what a vocabulary file holds");
	infoCmd->add_option("vocab", infoFile, "vocabulary file")
	    ->required()
	    ->check(CLI::ExistingFile.description(""))
	    ->type_name("FILE");

	std::string convertIn, convertOut;
	CLI::App* convertCmd = cli::subcommand(
	    app, "convert",
	    "rewrite a vocabulary file in the current format (with its checksum), e.g. an older one");
	convertCmd->add_option("vocab", convertIn, "vocabulary file to read")
	    ->required()
	    ->check(CLI::ExistingFile.description(""))
	    ->type_name("FILE");
	convertCmd->add_option("-o,--output", convertOut, "vocabulary file to write (may be the input)")
	    ->required()
	    ->type_name("FILE");

	BenchArgs b;
	CLI::App* benchCmd = cli::subcommand(
	    app, "bench", "time database queries on synthetic bags of words (Zipf-like word draws)");
	benchCmd->add_option("--vocab", b.vocab, "vocabulary file")
	    ->required()
	    ->check(CLI::ExistingFile.description(""))
	    ->type_name("FILE");
	benchCmd
	    ->add_option("--entries", b.sizes,
	                 "database sizes to time, comma-separated (each 1..1000000; default "
	                 "100,1000,10000)")
	    ->delimiter(',')
	    ->check(CLI::Range(std::size_t{1}, std::size_t{1000000}).description(""))
	    ->type_name("N");
	benchCmd->add_option("--seed", b.seed, "seed of the synthetic bags (default 1)")
	    ->type_name("S");

	if (const int rc = cli::parse(app, argc, argv); rc >= 0)
		return rc;
	try
	{
		if (trainCmd->parsed())
			return train(t);
		if (infoCmd->parsed())
			return info(infoFile);
		if (convertCmd->parsed())
		{
			bow::Vocabulary voc;
			if (!load(convertIn, voc))
				return cli::kExitError;
			bow::saveVocabularyFile(voc, convertOut);
			std::cout << "wrote " << convertOut << " (" << voc.words() << " words)\n";
			return 0;
		}
		return bench(b);
	}
	catch (const std::exception& e)
	{
		std::cerr << "rasterslam-vocab: " << e.what() << "\n";
		return cli::kExitError;
	}
}
