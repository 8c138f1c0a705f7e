// Matches a rectified stereo pair with hnnstereo::Matcher and prints what it found.
#include <hnnstereo/hnnstereo.h>

#include <cstdio>
#include <cstdlib>
#include <exception>
#include <opencv2/imgcodecs.hpp>

int main(int argc, char** argv) {
  if (argc < 3) {
    std::fprintf(stderr, "usage: match_pair LEFT RIGHT [MAX_DISPARITY]\n");
    return 2;
  }
  try {
    const cv::Mat left = cv::imread(argv[1], cv::IMREAD_UNCHANGED);
    const cv::Mat right = cv::imread(argv[2], cv::IMREAD_UNCHANGED);
    hnnstereo::Matcher matcher;  // preset hnn-default, OpenCL device from the environment
    const hnnstereo::MatchResult result = matcher.Match(left, right, argc > 3 ? std::atof(argv[3]) : 64.0);
    std::printf("%zu matches, engine %s on %s, %.1f ms\n", result.matches.size(),
                result.report.engine.c_str(), result.report.device.c_str(), result.report.timing_ms.total);
    for (std::size_t i = 0; i < result.matches.size() && i < 3; ++i) {
      const hnnstereo::Match& m = result.matches[i];
      std::printf("(%.1f, %.1f) -> (%.1f, %.1f) confidence %.2f\n", m.xl, m.yl, m.xr, m.yr, m.confidence);
    }
  } catch (const std::exception& error) {
    std::fprintf(stderr, "match_pair: error: %s\n", error.what());
    return 1;
  }
  return 0;
}
