// uninitialized.hpp — std::vector without value-initialization, for large arrays that are
// filled right after they are sized, in huge pages where the system has them. Private to the
// library.
//
// std::vector<T>::resize(n) zero-fills n elements on the calling thread before the program
// writes them again. For the summation tree's arrays (tens of MB on 10⁵ triangles) that pass,
// and the page faults it takes, was a fifth of the tree's build; with this allocator the
// pages are first touched by the (parallel) loops that fill them.
//
// Fresh memory costs a page fault per 4 KiB page at first touch, and on virtual machines a
// fault can cost 10 µs or more: on the 2-core machine gsd is measured on, 37 MB of fresh
// memory took 110 ms to touch, against 5 ms in 2 MiB pages. So blocks of kLargeBlock bytes or
// more are aligned to 2 MiB, rounded up to a multiple of it, and advised as transparent huge
// pages (Linux; where THP is off or not offered the advice is ignored, and only the alignment
// and the rounding remain). A block from malloc's heap keeps the advice after it is freed, for
// whatever malloc puts there next: huge pages again, where the system has them.
#pragma once

#include <cstddef>
#include <memory>
#include <new>
#include <type_traits>
#include <utility>
#include <vector>

namespace gsd::detail {

/// Blocks of this many bytes (4 MiB) or more go to allocate_large.
constexpr std::size_t kLargeBlock = std::size_t(4) << 20;
/// `bytes` aligned to 2 MiB and advised as huge pages; throws std::bad_alloc. Release with
/// release_large.
void* allocate_large(std::size_t bytes);
void release_large(void* p) noexcept;
/// Advises the whole 2 MiB pages inside [p, p + bytes) as huge pages, for memory allocated
/// elsewhere and not yet touched (a software Vulkan device's buffers: gpu::Buffer).
void advise_huge_pages(void* p, std::size_t bytes) noexcept;

/// An allocator whose construct() with no arguments default-initializes (leaves trivial types
/// unset); with arguments it constructs as usual. Blocks of kLargeBlock bytes or more come
/// from allocate_large.
template <class T>
struct UninitializedAllocator : std::allocator<T> {
    using std::allocator<T>::allocator;
    template <class U>
    struct rebind {
        using other = UninitializedAllocator<U>;
    };
    // Large: n·sizeof(T) ≥ kLargeBlock, without overflow. The same test on both sides.
    static bool large(std::size_t n) { return n >= (kLargeBlock + sizeof(T) - 1) / sizeof(T); }
    T* allocate(std::size_t n) {
        if (large(n)) {
            if (n > std::size_t(-1) / sizeof(T)) throw std::bad_array_new_length();
            return static_cast<T*>(allocate_large(n * sizeof(T)));
        }
        return std::allocator<T>::allocate(n);
    }
    void deallocate(T* p, std::size_t n) noexcept {
        if (large(n)) release_large(p);
        else std::allocator<T>::deallocate(p, n);
    }
    template <class U>
    void construct(U* p) noexcept(std::is_nothrow_default_constructible_v<U>) {
        ::new (static_cast<void*>(p)) U;
    }
    template <class U, class... Args>
    void construct(U* p, Args&&... args) {
        ::new (static_cast<void*>(p)) U(std::forward<Args>(args)...);
    }
};

/// A vector whose resize() leaves new elements of trivial type unset: write every one before
/// reading it.
template <class T>
using UninitializedVector = std::vector<T, UninitializedAllocator<T>>;

/// A plain std::vector (one an API returns) sized to n value-initialized elements, its new
/// storage advised as huge pages before the zeroing first touches it where it is large: the
/// zeroing runs on one thread, a fault per 4 KiB page (~11 µs each on the machine measured).
/// The device multigrid's 16 MB result: `shm grid tooth.ply --grid 128` on lavapipe
/// 27.9–29.9k → 25.4–26.1k page faults, step 3 0.63–0.68 → 0.58–0.61 s, three runs in turn.
template <class T>
void resize_in_huge_pages(std::vector<T>& v, std::size_t n) {
    if (n > v.capacity() && n >= (kLargeBlock + sizeof(T) - 1) / sizeof(T)) {
        std::vector<T> fresh;
        fresh.reserve(n);  // storage not yet touched
        advise_huge_pages(fresh.data(), n * sizeof(T));
        fresh.assign(v.begin(), v.end());
        v.swap(fresh);
    }
    v.resize(n);
}

}  // namespace gsd::detail
