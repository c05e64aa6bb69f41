// field_device.hpp — any gsd::Field on a device (gpu::evaluate_into's dispatch, the host fallback
// of a field without a device program, and points evaluated through a program for the
// renderer's wavefront march). Private to the library; built with Vulkan only.
#pragma once

#include <gsd/core.hpp>
#include <gsd/field.hpp>

#include <memory>

namespace gsd::gpu {

class Context;
struct BufferSpan;

/// Throws gsd::Error (`what`) for a span without a buffer or at an offset that is not a multiple
/// of the device's minStorageBufferOffsetAlignment.
void check_span(const Context& ctx, const BufferSpan& span, const char* what);

/// φ (and ∇φ) at host points, through `field`'s device program on `ctx` (the queries uploaded,
/// gpu::evaluate_into, the results read back); FieldValues::device names the device.
FieldValues evaluate_points(const Field& field, const std::shared_ptr<Context>& ctx, const Points& x, bool gradient);

}  // namespace gsd::gpu
