#include "core/uninitialized.hpp"

#include <cstdlib>
#include <new>

#if defined(__linux__)
#include <sys/mman.h>
#endif

namespace gsd::detail {

void* allocate_large(std::size_t bytes) {
    constexpr std::size_t huge = std::size_t(2) << 20;
    const std::size_t rounded = (bytes + huge - 1) / huge * huge;  // aligned_alloc wants a multiple
    if (rounded < bytes) throw std::bad_alloc();
    void* p = std::aligned_alloc(huge, rounded);
    if (!p) throw std::bad_alloc();
#if defined(__linux__) && defined(MADV_HUGEPAGE)
    // Advice only: on failure (no THP, an old kernel) the block is used in small pages.
    (void)madvise(p, rounded, MADV_HUGEPAGE);
#endif
    return p;
}

void release_large(void* p) noexcept { std::free(p); }

}  // namespace gsd::detail
