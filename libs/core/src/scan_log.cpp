#include <fcntl.h>
#include <rasterslam/core/scan_log.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <stdexcept>
#include <type_traits>

namespace fs = std::filesystem;

namespace rasterslam
{
// Records go to the file as their bytes: only a type with no pointers inside may.
static_assert(std::is_trivially_copyable_v<ScanRecord>,
              "ScanLog writes ScanRecord's bytes: it must stay trivially copyable");

namespace
{
// Records buffered before a write: 256 x 264 bytes, one 66 kB write.
constexpr std::size_t kBatch = 256;

std::string reason(int e)
{
	return std::strerror(e != 0 ? e : EIO);
}
}  // namespace

int openUnnamedTempFile(const std::string& dir, const std::string& what)
{
	std::string folder = dir;
	if (folder.empty())
		if (const char* t = std::getenv("TMPDIR"); t && *t)
			folder = t;
	if (folder.empty())
		folder = "/tmp";
	std::string name = (fs::path(folder) / "rasterslam-XXXXXX").string();
	const int fd = ::mkostemp(name.data(), O_CLOEXEC);  // not inherited by child processes
	if (fd < 0)
	{
		const int e = errno;
		throw std::runtime_error("no temporary file for " + what + " in '" + folder +
		                         "': " + reason(e));
	}
	// Unnamed from now on: gone when closed, however the process ends.
	if (::unlink(name.c_str()) != 0)
	{
		const int e = errno;
		::close(fd);
		throw std::runtime_error("the temporary file for " + what + " in '" + folder +
		                         "' cannot be unnamed: " + reason(e));
	}
	return fd;
}

ScanLog ScanLog::spooled(const std::string& dir)
{
	return onDescriptor(openUnnamedTempFile(dir, "the scan records"));
}

ScanLog ScanLog::onDescriptor(int fd)
{
	if (fd < 0)
		throw std::invalid_argument("ScanLog: no file");
	ScanLog log;
	log.fd_ = fd;
	log.mem_.reserve(kBatch);
	return log;
}

ScanLog::ScanLog(ScanLog&& o) noexcept
    : mem_(std::move(o.mem_)),
      size_(o.size_),
      written_(o.written_),
      fd_(o.fd_),
      error_(std::move(o.error_))
{
	o.fd_ = -1;
	o.size_ = o.written_ = 0;
	o.mem_.clear();
}

ScanLog& ScanLog::operator=(ScanLog&& o) noexcept
{
	if (this != &o)
	{
		if (fd_ >= 0)
			::close(fd_);
		mem_ = std::move(o.mem_);
		size_ = o.size_;
		written_ = o.written_;
		fd_ = o.fd_;
		error_ = std::move(o.error_);
		o.fd_ = -1;
		o.size_ = o.written_ = 0;
		o.mem_.clear();
	}
	return *this;
}

ScanLog::~ScanLog()
{
	if (fd_ >= 0)
		::close(fd_);
}

void ScanLog::flushPending()
{
	if (fd_ < 0 || mem_.empty())
		return;
	if (error_.empty())
	{
		const auto* p = reinterpret_cast<const char*>(mem_.data());
		std::size_t left = mem_.size() * sizeof(ScanRecord);
		auto at = static_cast<off_t>(written_ * sizeof(ScanRecord));
		while (left > 0)
		{
			const ssize_t n = ::pwrite(fd_, p, left, at);
			if (n < 0 && errno == EINTR)
				continue;
			if (n <= 0)
			{
				const int e = n < 0 ? errno : ENOSPC;
				error_ = "the scan records could not be kept in a temporary file (" + reason(e) +
				         "): " + std::to_string(size_ - written_) +
				         " and any later are lost, and with them the run's trajectory";
				break;
			}
			p += n;
			left -= static_cast<std::size_t>(n);
			at += n;
		}
	}
	// Lost ones count as written: their places in the file stay unreadable (error_ says why).
	written_ += mem_.size();
	mem_.clear();
}

void ScanLog::push_back(const ScanRecord& r)
{
	mem_.push_back(r);
	++size_;
	if (fd_ >= 0 && mem_.size() >= kBatch)
		flushPending();
}

void ScanLog::readSpooled(std::size_t first, std::size_t n, ScanRecord* out) const
{
	if (!error_.empty())
		throw std::runtime_error(error_);
	auto* p = reinterpret_cast<char*>(out);
	std::size_t left = n * sizeof(ScanRecord);
	auto at = static_cast<off_t>(first * sizeof(ScanRecord));
	while (left > 0)
	{
		const ssize_t got = ::pread(fd_, p, left, at);
		if (got < 0 && errno == EINTR)
			continue;
		if (got <= 0)
			throw std::runtime_error("the scan records' temporary file could not be read back (" +
			                         (got < 0 ? reason(errno) : std::string("it ended early")) +
			                         ")");
		p += got;
		left -= static_cast<std::size_t>(got);
		at += got;
	}
}

ScanRecord ScanLog::operator[](std::size_t i) const
{
	if (i >= size_)
		throw std::out_of_range("ScanLog: record " + std::to_string(i) + " of " +
		                        std::to_string(size_));
	if (fd_ < 0)
		return mem_[i];
	if (i >= written_)
		return mem_[i - written_];
	ScanRecord r;
	readSpooled(i, 1, &r);
	return r;
}

void ScanLog::modify(std::size_t i, const std::function<void(ScanRecord&)>& f)
{
	if (i >= size_)
		throw std::out_of_range("ScanLog: record " + std::to_string(i) + " of " +
		                        std::to_string(size_));
	if (fd_ < 0 || i >= written_)
	{
		f(mem_[fd_ < 0 ? i : i - written_]);
		return;
	}
	ScanRecord r;
	readSpooled(i, 1, &r);
	f(r);
	const auto at = static_cast<off_t>(i * sizeof(ScanRecord));
	ssize_t n;
	do
		n = ::pwrite(fd_, &r, sizeof r, at);
	while (n < 0 && errno == EINTR);
	if (n != static_cast<ssize_t>(sizeof r))
	{
		const int e = n < 0 ? errno : ENOSPC;
		throw std::runtime_error("the scan records' temporary file could not be updated (" +
		                         reason(e) + ")");
	}
}

void ScanLog::forEach(const std::function<void(const ScanRecord&)>& f) const
{
	if (fd_ < 0)
	{
		for (const auto& r : mem_)
			f(r);
		return;
	}
	std::vector<ScanRecord> chunk(std::min(kBatch, written_));
	for (std::size_t i = 0; i < written_; i += chunk.size())
	{
		const std::size_t n = std::min(chunk.size(), written_ - i);
		readSpooled(i, n, chunk.data());
		for (std::size_t k = 0; k < n; k++)
			f(chunk[k]);
	}
	for (const auto& r : mem_)
		f(r);
}

}  // namespace rasterslam
