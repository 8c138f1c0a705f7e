// Points files ("X Y Z u v" per line): finite, bounded numbers or a std::exception (what the CLI turns into one line).
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <exception>

#include "calib/known_points.h"
#include "fuzz_support.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  try {
    const hnnstereo::calib::KnownPoints points =
        hnnstereo::calib::ParseKnownPoints(hnnstereo::fuzz::AsText(data, size), "fuzz");
    for (const auto& point : points.points3D_in_world) {
      if (!point.allFinite() || point.cwiseAbs().maxCoeff() > 1e7) __builtin_trap();
    }
  } catch (const std::exception&) {  // what the CLI turns into its one-line error
  }
  return 0;
}
