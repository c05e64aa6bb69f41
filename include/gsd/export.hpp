// gsd/export.hpp — GSD_EXPORT marks the public API.
//
// libgsd is compiled with hidden visibility: only declarations marked GSD_EXPORT are exported
// from the shared library. Everything else — internal modules, the Vulkan loader's function
// pointers — stays inside it, so an application that links libvulkan or its own loader next to
// gsd sees no clashing symbols.
#pragma once

#if defined(__GNUC__) || defined(__clang__)
#define GSD_EXPORT __attribute__((visibility("default")))
#else
#define GSD_EXPORT
#endif
