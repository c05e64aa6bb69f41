// uninitialized.hpp — std::vector without value-initialization, for large arrays that are
// filled right after they are sized. Private to the library.
//
// std::vector<T>::resize(n) zero-fills n elements on the calling thread before the program
// writes them again. For the summation tree's arrays (tens of MB on 10⁵ triangles) that pass,
// and the page faults it takes, was a fifth of the tree's build; with this allocator the
// pages are first touched by the (parallel) loops that fill them.
#pragma once

#include <memory>
#include <new>
#include <type_traits>
#include <utility>
#include <vector>

namespace gsd::detail {

/// An allocator whose construct() with no arguments default-initializes (leaves trivial types
/// unset); with arguments it constructs as usual.
template <class T>
struct UninitializedAllocator : std::allocator<T> {
    using std::allocator<T>::allocator;
    template <class U>
    struct rebind {
        using other = UninitializedAllocator<U>;
    };
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

}  // namespace gsd::detail
