// The consumer's Vulkan interop check (interop.cpp).
#pragma once

#include <gsd/pat.hpp>

#include <string>

/// Runs gsd on a device the application created itself and compares with the CPU; true if all
/// agree. With a `picture` path, also renders the field's zero set on that device (gsd render's
/// code, FieldRenderOptions::device = the adopted context), writes it there as PNG and requires
/// it to match the CPU's picture.
bool interop_check(const gsd::FittedTori& tori, const gsd::Points& queries, const std::string& picture = {});
