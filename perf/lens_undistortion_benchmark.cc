// Google Benchmark: what undistorting costs `pick` on a calibration with lens distortion
// (docs/decisions.md, "Lens distortion: images undistorted"). The image route resamples both
// images (UndistortImage, as `pick`, `match` and `serve` do); the point route would undistort
// only the features' coordinates (UndistortPoints, 4,000 per image: the pick cell's cap).
// Run: build/perf/hnnstereo_lens_undistortion_benchmark
#include <benchmark/benchmark.h>

#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <random>
#include <vector>

#include "vision/stereo/lens_distortion.h"

namespace {

using namespace hnnstereo;

const std::vector<double> kDistortion = {-0.25, 0.08, 0.001, -0.001};  // render --distortion

// The cell's camera at width x 3/4 width: focal 1100 px at 640 px, scaled with the width.
Eigen::Matrix3d CellCamera(int width) {
  const double focal = 1100.0 * width / 640.0;
  Eigen::Matrix3d K;
  K << focal, 0, 0.5 * width, 0, focal, 0.375 * width, 0, 0, 1;
  return K;
}

void BM_UndistortImagePair(benchmark::State& state) {
  const int width = static_cast<int>(state.range(0));
  cv::Mat left(width * 3 / 4, width, CV_8UC1), right(left.size(), CV_8UC1);
  cv::randu(left, 0, 255);
  cv::randu(right, 0, 255);
  const Eigen::Matrix3d K = CellCamera(width);
  for (auto _ : state) {
    benchmark::DoNotOptimize(vision::UndistortImage(left, K, kDistortion));
    benchmark::DoNotOptimize(vision::UndistortImage(right, K, kDistortion));
  }
}
BENCHMARK(BM_UndistortImagePair)->Arg(640)->Arg(2048)->Unit(benchmark::kMillisecond);

void BM_UndistortFeaturePair(benchmark::State& state) {
  const int width = static_cast<int>(state.range(0));
  std::mt19937 random(7);
  const float w = static_cast<float>(width);
  std::uniform_real_distribution<float> u(0.0f, w - 1.0f), v(0.0f, 0.75f * w - 1.0f);
  std::vector<Eigen::Vector2f> features(4000);
  for (auto& p : features) p = {u(random), v(random)};
  const Eigen::Matrix3d K = CellCamera(width);
  for (auto _ : state) {
    benchmark::DoNotOptimize(vision::UndistortPoints(features, K, kDistortion));
    benchmark::DoNotOptimize(vision::UndistortPoints(features, K, kDistortion));
  }
}
BENCHMARK(BM_UndistortFeaturePair)->Arg(640)->Arg(2048)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
