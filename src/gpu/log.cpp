#include <gsd/gpu.hpp>

#include <cstdio>
#include <mutex>
#include <set>

namespace gsd {

namespace {
std::mutex log_mutex;
std::function<void(std::string_view)>& sink() {
    static std::function<void(std::string_view)> s = [](std::string_view m) {
        std::fprintf(stderr, "gsd: %.*s\n", int(m.size()), m.data());
    };
    return s;
}
}  // namespace

void set_log_sink(std::function<void(std::string_view)> s) {
    std::lock_guard<std::mutex> lock(log_mutex);
    sink() = std::move(s);
}

void log_once(const std::string& message) {
    static std::set<std::string> seen;
    std::lock_guard<std::mutex> lock(log_mutex);
    if (!seen.insert(message).second) return;
    if (sink()) sink()(message);
}

}  // namespace gsd
