// The color map and level lines shared by render_slice and render_surface, and the public
// diverging_color that lets other outputs (colored meshes) match the pictures.
#include "viz/palette.hpp"

#include <gsd/viz.hpp>

#include <algorithm>
#include <cmath>

namespace gsd {
namespace viz {

Rgb mix(const Rgb& a, const Rgb& b, double t) {
    return {a.r + (b.r - a.r) * t, a.g + (b.g - a.g) * t, a.b + (b.b - a.b) * t};
}

Rgb diverging(double s) {
    static constexpr std::array<Rgb, 11> stops{{
        {5, 48, 97}, {33, 102, 172}, {67, 147, 195}, {146, 197, 222}, {209, 229, 240},
        {255, 255, 255},
        {253, 219, 199}, {244, 165, 130}, {214, 96, 77}, {178, 24, 43}, {103, 0, 31},
    }};
    const double f = (std::clamp(s, -1.0, 1.0) + 1) * 0.5 * (stops.size() - 1);
    const std::size_t n = std::min(std::size_t(f), stops.size() - 2);
    return mix(stops[n], stops[n + 1], f - double(n));
}

std::uint8_t to_byte(double c) { return static_cast<std::uint8_t>(std::lround(std::clamp(c, 0.0, 255.0))); }

std::array<std::uint8_t, 3> to_bytes(const Rgb& c) { return {to_byte(c.r), to_byte(c.g), to_byte(c.b)}; }

double line_coverage(double distance, double half_width) {
    return std::clamp(half_width + 0.5 - distance, 0.0, 1.0);
}

Rgb LevelLines::draw(Rgb c, double value, double gradient) const {
    // Where the field is flat, the first-order distance blows up: no line, as it should be.
    const double g = std::max(gradient, 1e-300);
    if (spacing_ > 0) c = mix(c, style_.iso_color, isoline_alpha(value, g));
    if (zero_contour_) c = mix(c, style_.zero_color, line_coverage(std::abs(value) / g, style_.zero_half_width));
    return c;
}

// Coverage of the nearest isoline (level k·spacing; k = 0 belongs to the zero contour when that
// is drawn). Isolines fade out where they crowd closer than min_gap pixels, so steep regions
// read as a darker tone instead of moiré.
double LevelLines::isoline_alpha(double value, double g) const {
    const double k0 = std::floor(value / spacing_);
    double distance = INFINITY;
    for (double k : {k0, k0 + 1}) {
        if (k == 0 && zero_contour_) continue;
        distance = std::min(distance, std::abs(value - k * spacing_) / g);
    }
    const double gap = spacing_ / g;  // pixels between neighboring isolines
    const double fade = std::clamp((gap - style_.min_gap) / style_.min_gap, 0.0, 1.0);
    return style_.iso_opacity * fade * line_coverage(distance, style_.iso_half_width);
}

}  // namespace viz

std::array<std::uint8_t, 3> diverging_color(double x, double range) {
    if (!(range > 0) || !std::isfinite(range)) throw Error("range", "color range must be positive and finite");
    if (std::isnan(x)) return viz::to_bytes(viz::kNoValue);
    return viz::to_bytes(viz::diverging(x / range));
}

}  // namespace gsd
