#pragma once
// Number formatting for reports and overlays.

#include <cstdio>
#include <string>

namespace hnnstereo::common {

/// `value` in fixed notation with `digits` digits after the point ("%.*f", C locale), whole.
inline std::string Fixed(double value, int digits = 3) {
  const int length = std::snprintf(nullptr, 0, "%.*f", digits, value);
  if (length <= 0) return {};
  std::string text(static_cast<std::size_t>(length), '\0');
  std::snprintf(text.data(), text.size() + 1, "%.*f", digits, value);
  return text;
}

}  // namespace hnnstereo::common
