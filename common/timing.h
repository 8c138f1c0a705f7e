#pragma once
// Wall-clock timing of pipeline stages (the reports' *_ms fields).

#include <chrono>

namespace hnnstereo::common {

/// Milliseconds elapsed on the steady clock since `start`.
inline double MillisecondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace hnnstereo::common
