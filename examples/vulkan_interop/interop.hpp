// The consumer's Vulkan interop check (interop.cpp).
#pragma once

#include <gsd/pat.hpp>

/// Runs gsd on a device the consumer created itself and compares with the CPU; true if all agree.
bool interop_check(const gsd::FittedTori& tori, const gsd::Points& queries);
