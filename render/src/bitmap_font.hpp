#pragma once

// A tiny 5×7 dot font of our own (capitals, digits and a little punctuation) for labels drawn as
// quads, so the renderer needs no font files or font library. Internal to render/.

#include <array>
#include <cstdint>
#include <string_view>

namespace ultrasim::render::detail {

inline constexpr int kGlyphWidthDots = 5;
inline constexpr int kGlyphHeightDots = 7;
inline constexpr int kGlyphAdvanceDots = 6;  // one blank column between glyphs

// The glyph's 7 rows, top first; bit 4 of each row is the leftmost dot. Lower-case letters use
// the capitals; characters without a glyph show as '?'. No allocation, any thread.
const std::array<std::uint8_t, kGlyphHeightDots>& glyph_rows(char c);

// Width of text in dots (0 for empty text).
inline int text_width_dots(std::string_view text) {
  return text.empty() ? 0 : static_cast<int>(text.size()) * kGlyphAdvanceDots - 1;
}

}  // namespace ultrasim::render::detail
