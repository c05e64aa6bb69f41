// palette.hpp — what the slice and surface pictures share, so that both read the same: the
// diverging color map, the anti-aliased level lines drawn from a per-pixel distance estimate,
// and byte conversion. Private to src/viz.
#pragma once

#include <array>
#include <cstdint>

namespace gsd::viz {

struct Rgb {
    double r, g, b;
};

/// Surfaces with no value to show: faces touching a NaN vertex value, and plain meshes.
inline constexpr Rgb kNoValue{170, 170, 170};

Rgb mix(const Rgb& a, const Rgb& b, double t);

/// ColorBrewer RdBu (reversed so that blue is negative) with a pure white center; s runs from
/// −1 (deep blue) to +1 (deep red) and saturates beyond.
Rgb diverging(double s);

std::uint8_t to_byte(double c);
std::array<std::uint8_t, 3> to_bytes(const Rgb& c);

/// Fraction of a pixel covered by a line of the given half width whose center is `distance`
/// pixels away (a one-pixel linear ramp at the edge is the anti-aliasing).
double line_coverage(double distance, double half_width);

/// How level lines look; widths and gaps in pixels (of whatever image they are drawn into).
struct LineStyle {
    double iso_half_width, iso_opacity, zero_half_width;
    Rgb iso_color, zero_color;
    double min_gap;  ///< isolines fade out where they would be closer than about this
};

/// Thin isolines at every multiple of `spacing` (none if spacing is 0) and, if asked, a thick
/// zero contour, drawn per pixel from the distance to the nearest level estimated to first
/// order as |value − level| / |∇value|, with the gradient in value per pixel. Every line then
/// has the same width in pixels whether the field is steep or flat.
class LevelLines {
public:
    LevelLines(double spacing, bool zero_contour, const LineStyle& style)
        : spacing_(spacing), zero_contour_(zero_contour), style_(style) {}

    Rgb draw(Rgb c, double value, double gradient) const;

private:
    double isoline_alpha(double value, double gradient) const;

    double spacing_;
    bool zero_contour_;
    LineStyle style_;
};

}  // namespace gsd::viz
