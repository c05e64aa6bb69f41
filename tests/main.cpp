// The test runner shared by every suite: doctest's, plus a watch on Vulkan validation.
//
// Validation layers are on in every CTest run (GSD_VALIDATION=1). Each test case is watched: a
// validation error raised while it runs — by this process's GPU work (the layer's callback counts
// them) or by a CLI process it started (run_cli scans their output) — fails the suite, naming the
// test case, even when the case itself checks nothing about the GPU. What the layer reports when
// the devices are destroyed at exit (objects gsd forgot to destroy) fails the run too.
#define DOCTEST_CONFIG_IMPLEMENT
#include <doctest/doctest.h>

#include <gsd/gpu.hpp>

#include "support.hpp"

#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

namespace {

std::vector<std::string> g_offenders;  // test cases that raised a validation error

// Validation errors so far that no test case asked for.
std::uint64_t unexpected_validation_errors() {
    return gsd::gpu::validation_error_count() + gsd::test::cli_validation_errors() -
           gsd::test::expected_validation_errors();
}

struct ValidationWatch : doctest::IReporter {
    std::uint64_t at_start = 0;
    explicit ValidationWatch(const doctest::ContextOptions&) {}

    void test_case_start(const doctest::TestCaseData& tc) override {
        current_ = tc.m_name;
        at_start = unexpected_validation_errors();
    }
    void test_case_end(const doctest::CurrentTestCaseStats&) override {
        if (unexpected_validation_errors() > at_start) g_offenders.push_back(current_);
    }
    void test_case_reenter(const doctest::TestCaseData&) override {}
    void test_case_exception(const doctest::TestCaseException&) override {}
    void subcase_start(const doctest::SubcaseSignature&) override {}
    void subcase_end() override {}
    void log_assert(const doctest::AssertData&) override {}
    void log_message(const doctest::MessageData&) override {}
    void test_case_skipped(const doctest::TestCaseData&) override {}
    void report_query(const doctest::QueryData&) override {}
    void test_run_start() override {}
    void test_run_end(const doctest::TestRunStats&) override {}

    std::string current_;
};

}  // namespace

REGISTER_LISTENER("validation-watch", 1, ValidationWatch);

std::uint64_t g_counted_by_main = 0;

// Runs after the GPU runtime's static destructor (it is registered before the runtime exists),
// so it sees what the validation layer says when the devices go away: any object not destroyed.
void check_at_exit() {
    const std::uint64_t now = unexpected_validation_errors();
    if (now > g_counted_by_main) {
        std::fprintf(stderr, "FAILED: %llu Vulkan validation error(s) while the devices were destroyed at exit "
                             "(messages above; an object not destroyed?)\n",
                     static_cast<unsigned long long>(now - g_counted_by_main));
        std::_Exit(1);
    }
}

int main(int argc, char** argv) {
    std::atexit(check_at_exit);
    doctest::Context context(argc, argv);
    const int rc = context.run();
    if (context.shouldExit()) return rc;
    g_counted_by_main = unexpected_validation_errors();
    if (!g_offenders.empty() || unexpected_validation_errors() > 0) {
        std::fprintf(stderr, "\nFAILED: %llu Vulkan validation error(s) (messages above)",
                     static_cast<unsigned long long>(unexpected_validation_errors()));
        for (const std::string& name : g_offenders) std::fprintf(stderr, "\n  raised in: %s", name.c_str());
        std::fprintf(stderr, "\n");
        return rc != 0 ? rc : 1;
    }
    return rc;
}
