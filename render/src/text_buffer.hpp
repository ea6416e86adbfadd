#pragma once

// Builds short labels ("DEPTH 4.0 CM", "FRAME 1234") on the stack, so per-frame text costs no
// heap allocation. Internal to render/.

#include <array>
#include <cctype>
#include <charconv>
#include <cstdint>
#include <string_view>

namespace ultrasim::render::detail {

class TextBuffer {
 public:
  TextBuffer& append(std::string_view text) {
    for (const char c : text) {
      if (size_ < chars_.size()) chars_[size_++] = c;
    }
    return *this;
  }
  // In capitals: the bitmap font has no small letters.
  TextBuffer& append_upper(std::string_view text) {
    for (const char c : text) {
      if (size_ < chars_.size()) {
        chars_[size_++] = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
      }
    }
    return *this;
  }
  TextBuffer& append_int(std::int64_t value) {
    const auto [end, ec] =
        std::to_chars(chars_.data() + size_, chars_.data() + chars_.size(), value);
    if (ec == std::errc()) size_ = static_cast<std::size_t>(end - chars_.data());
    return *this;
  }
  // Fixed-point with the given number of decimals ("4.0").
  TextBuffer& append_fixed(float value, int decimals) {
    const auto [end, ec] = std::to_chars(chars_.data() + size_, chars_.data() + chars_.size(),
                                         value, std::chars_format::fixed, decimals);
    if (ec == std::errc()) size_ = static_cast<std::size_t>(end - chars_.data());
    return *this;
  }
  std::string_view view() const { return {chars_.data(), size_}; }

 private:
  std::array<char, 64> chars_{};
  std::size_t size_ = 0;
};

}  // namespace ultrasim::render::detail
