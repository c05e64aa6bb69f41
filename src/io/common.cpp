// Shared plumbing of the io module: whole-file reads, atomic writes, error text, and the
// text scanner/number parser every text format uses.
#include "io/io_internal.hpp"

#include <atomic>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <random>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

namespace gsd::io {

namespace fs = std::filesystem;

namespace detail {

[[noreturn]] void fail(const std::string& path, const std::string& what) { throw Error(path, what); }

std::string at_line(std::size_t line, const std::string& what) {
    return "line " + std::to_string(line) + ": " + what;
}

std::string quoted(std::string_view token) {
    constexpr std::size_t kMax = 24;
    std::string out = "'";
    for (std::size_t i = 0; i < token.size() && i < kMax; ++i) {
        const auto c = static_cast<unsigned char>(token[i]);
        if (std::isprint(c)) {
            out += char(c);
        } else {
            char hex[8];
            std::snprintf(hex, sizeof hex, "\\x%02x", c);
            out += hex;
        }
    }
    if (token.size() > kMax) out += "...";
    return out + "'";
}

// ---- files ----------------------------------------------------------------------------

namespace {

std::string errno_text(int err) { return std::generic_category().message(err); }

/// Opens `path` for reading after checking that it is a regular file; returns the fd and size.
int open_regular_file(const std::string& path, std::size_t& size) {
    struct stat st {};
    if (::stat(path.c_str(), &st) != 0) {
        const int err = errno;
        if (err == ENOENT) fail(path, "file not found");
        fail(path, "cannot open file: " + errno_text(err));
    }
    if (S_ISDIR(st.st_mode)) fail(path, "is a directory, not a file");
    if (!S_ISREG(st.st_mode)) fail(path, "is not a regular file");
    const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd < 0) fail(path, "cannot open file: " + errno_text(errno));
    size = static_cast<std::size_t>(st.st_size);
    return fd;
}

}  // namespace

void require_regular_file(const std::string& path) {
    std::size_t size = 0;
    ::close(open_regular_file(path, size));
    if (size == 0) fail(path, "file is empty");
}

std::string read_whole_file(const std::string& path) {
    std::size_t size = 0;
    const int fd = open_regular_file(path, size);
    std::string bytes(size, '\0');
    std::size_t done = 0;
    while (done < size) {
        const ssize_t got = ::read(fd, bytes.data() + done, size - done);
        if (got < 0 && errno == EINTR) continue;
        if (got <= 0) {
            const int err = errno;
            ::close(fd);
            if (got == 0) fail(path, "file shrank while it was being read");
            fail(path, "read error: " + errno_text(err));
        }
        done += std::size_t(got);
    }
    ::close(fd);
    if (size == 0) fail(path, "file is empty");
    return bytes;
}

// ---- text scanning ----------------------------------------------------------------------

bool LineScanner::next(std::string_view& line) {
    if (rest_.empty()) return false;
    const std::size_t end = rest_.find('\n');
    line = rest_.substr(0, end);
    rest_ = end == std::string_view::npos ? std::string_view{} : rest_.substr(end + 1);
    ++line_;
    comment_ = {};
    if (const std::size_t hash = line.find('#'); hash != std::string_view::npos) {
        comment_ = line.substr(hash + 1);
        line = line.substr(0, hash);
    }
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    return true;
}

bool Tokens::is_separator(char c) const {
    return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f' || (commas_ && c == ',');
}

bool Tokens::next(std::string_view& token) {
    std::size_t i = 0;
    while (i < rest_.size() && is_separator(rest_[i])) ++i;
    if (i == rest_.size()) {
        rest_ = {};
        return false;
    }
    std::size_t j = i;
    while (j < rest_.size() && !is_separator(rest_[j])) ++j;
    token = rest_.substr(i, j - i);
    rest_ = rest_.substr(j);
    return true;
}

std::size_t Tokens::count_left() const {
    Tokens copy = *this;
    std::size_t n = 0;
    std::string_view t;
    while (copy.next(t)) ++n;
    return n;
}

bool parse_double(std::string_view token, double& out) {
    // from_chars rejects a leading '+', which text writers do emit ("+1.5e+00").
    if (!token.empty() && token.front() == '+') token.remove_prefix(1);
    if (token.empty()) return false;
    const char* end = token.data() + token.size();
    const auto r = std::from_chars(token.data(), end, out);
    return r.ec == std::errc{} && r.ptr == end;
}

bool parse_int(std::string_view token, long long& out) {
    if (!token.empty() && token.front() == '+') token.remove_prefix(1);
    if (token.empty()) return false;
    const char* end = token.data() + token.size();
    const auto r = std::from_chars(token.data(), end, out);
    return r.ec == std::errc{} && r.ptr == end;
}

double finite_number(std::string_view token, const std::string& path, std::size_t line,
                     const char* what) {
    double v = 0;
    if (!parse_double(token, v))
        fail(path, at_line(line, std::string("expected ") + what + ", found " + quoted(token)));
    if (!std::isfinite(v))
        fail(path, at_line(line, "non-finite value " + quoted(token) + " (NaN and Inf are not allowed)"));
    return v;
}

void append_number(std::string& out, double v) {
    char buf[32];
    const auto r = std::to_chars(buf, buf + sizeof buf, v);
    out.append(buf, r.ptr);
}

std::uint64_t mul_sat(std::uint64_t a, std::uint64_t b) {
    std::uint64_t r = 0;
    return __builtin_mul_overflow(a, b, &r) ? std::numeric_limits<std::uint64_t>::max() : r;
}

std::uint64_t add_sat(std::uint64_t a, std::uint64_t b) {
    std::uint64_t r = 0;
    return __builtin_add_overflow(a, b, &r) ? std::numeric_limits<std::uint64_t>::max() : r;
}

PointCloud cloud_from_rows(const double* xyzn, std::size_t n, bool with_normals) {
    PointCloud c;
    const std::size_t stride = with_normals ? 6 : 3;
    c.points.resize(Eigen::Index(n), 3);
    if (with_normals) c.normals.resize(Eigen::Index(n), 3);
    for (std::size_t i = 0; i < n; ++i)
        for (int k = 0; k < 3; ++k) {
            c.points(Eigen::Index(i), k) = xyzn[stride * i + std::size_t(k)];
            if (with_normals) c.normals(Eigen::Index(i), k) = xyzn[stride * i + 3 + std::size_t(k)];
        }
    return c;
}

}  // namespace detail

// ---- public helpers ---------------------------------------------------------------------

std::string extension(const std::string& path) {
    std::string ext = fs::path(path).extension().string();
    for (char& c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
    return ext;
}

namespace {

/// A temp name beside `path` that no other writer (thread or process) will pick.
std::string temp_name_beside(const std::string& path) {
    static std::atomic<unsigned> counter{0};
    thread_local std::mt19937 rng{std::random_device{}()};
    return path + ".tmp-" + std::to_string(::getpid()) + "-" + std::to_string(counter++) + "-" +
           std::to_string(rng() % 1000000);
}

bool write_all(int fd, const std::string& bytes) {
    std::size_t done = 0;
    while (done < bytes.size()) {
        const ssize_t put = ::write(fd, bytes.data() + done, bytes.size() - done);
        if (put < 0 && errno == EINTR) continue;
        if (put <= 0) return false;
        done += std::size_t(put);
    }
    return true;
}

/// Writes straight into an existing character device or FIFO (`-o /dev/null`, `-o /dev/stdout`
/// into a pipe): such a target cannot be replaced by a rename, and must never be replaced by a
/// regular file.
void write_special_file(const std::string& path, const std::string& bytes) {
    const int fd = ::open(path.c_str(), O_WRONLY | O_CLOEXEC);
    if (fd < 0) throw Error(path, "cannot open output for writing: " + detail::errno_text(errno));
    const bool written = write_all(fd, bytes);
    const int err = errno;
    ::close(fd);
    if (!written) throw Error(path, "cannot write output: " + detail::errno_text(err));
}

}  // namespace

void write_file_atomic(const std::string& path_in, const std::string& bytes) {
    if (path_in.empty()) throw Error(path_in, "empty output path");
    std::string path = path_in;
    struct stat st {};
    if (::stat(path.c_str(), &st) == 0) {
        if (S_ISCHR(st.st_mode) || S_ISFIFO(st.st_mode)) return write_special_file(path, bytes);
        if (S_ISDIR(st.st_mode)) throw Error(path, "is a directory, not a file");
        if (!S_ISREG(st.st_mode)) throw Error(path, "is not a regular file; gsd will not replace it");
        // A symlink to a file: replace the file it points to, not the link.
        std::error_code ec;
        const fs::path real = fs::canonical(path, ec);
        if (!ec) path = real.string();
    }
    const std::string temp = temp_name_beside(path);
    // O_EXCL: never clobber someone else's file; mode 0666 so the umask decides, as for any
    // ordinary output file (mkstemp would leave 0600).
    const int fd = ::open(temp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
    if (fd < 0) {
        const int err = errno;
        const std::string dir = fs::path(path).parent_path().string();
        throw Error(path, "cannot create output file in '" + (dir.empty() ? "." : dir) +
                              "': " + detail::errno_text(err));
    }
    // fsync before rename: otherwise a crash soon after could leave the new name pointing
    // at an empty file on some file systems.
    const bool written = write_all(fd, bytes) && ::fsync(fd) == 0;
    const int write_err = errno;
    const bool closed = ::close(fd) == 0;
    if (!written || !closed) {
        ::unlink(temp.c_str());
        throw Error(path, "cannot write output file: " + detail::errno_text(written ? errno : write_err));
    }
    if (::rename(temp.c_str(), path.c_str()) != 0) {
        const int err = errno;
        ::unlink(temp.c_str());
        throw Error(path, "cannot replace output file: " + detail::errno_text(err));
    }
}

}  // namespace gsd::io
