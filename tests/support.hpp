// Shared helpers for the test suites: scratch folders, running the CLI, real data paths.
#pragma once

#include <gsd/core.hpp>

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace gsd::test {

/// A fresh empty folder under the system temp dir, removed when the object goes away.
class ScratchDir {
public:
    explicit ScratchDir(const std::string& tag);
    ~ScratchDir();
    ScratchDir(const ScratchDir&) = delete;
    ScratchDir& operator=(const ScratchDir&) = delete;
    std::string file(const std::string& name) const { return (path_ / name).string(); }
    const std::filesystem::path& path() const { return path_; }

private:
    std::filesystem::path path_;
};

/// Result of running a command: exit status and combined stdout+stderr.
struct RunResult {
    int exit_code = -1;
    std::string output;
};

/// Runs the built `gsd` CLI with `args` (a shell-quoted argument string).
RunResult run_cli(const std::string& args);
/// Runs an arbitrary shell command.
RunResult run_shell(const std::string& command);

/// Path of a file under ../shared/data (real inputs made by others).
std::string shared_data(const std::string& relative);

/// The generalized winding number of a mesh at each query by the plain exact sum (Jacobson et
/// al. 2013: each polygon fanned from its first corner, each triangle's signed solid angle by
/// Van Oosterom–Strackee, / 4π), written here apart from the library as an independent reference.
std::vector<double> brute_force_winding(const PolygonMesh& mesh, const Points& queries);

/// Exact signed distance in the plane z = 0 to a closed polygon (P[0] repeated at the end),
/// negative inside, at each point's projection.
std::vector<double> polygon_sdf(const Points& x, const std::vector<Eigen::Vector2d>& P);

/// Writes raw bytes to a file (for hand-made malformed inputs).
void write_bytes(const std::string& path, const std::string& bytes);

bool file_exists(const std::string& path);

/// Whether the suite runs under sanitizers (scripts/sanitize.sh; 10-30x slower there).
#if defined(GSD_TESTS_SANITIZED) && GSD_TESTS_SANITIZED
inline constexpr bool kSanitized = true;
#else
inline constexpr bool kSanitized = false;
#endif
/// A problem size: `full` in the Release suite, `sanitized` under sanitizers, where the same
/// checks run on less data so the suite fits in CI's time.
inline int sized(int full, int sanitized) { return kSanitized ? sanitized : full; }

/// Vulkan validation errors reported in the output of CLI runs (run_cli/run_shell) so far.
std::uint64_t cli_validation_errors();
/// Validation errors that tests provoked on purpose, so far (the runner does not count them).
std::uint64_t expected_validation_errors();
/// Declares that the calling test is about to provoke `n` validation errors on purpose.
void expect_validation_errors(std::uint64_t n);

}  // namespace gsd::test
