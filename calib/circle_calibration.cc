#include "calib/circle_calibration.h"

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <limits>
#include <opencv2/core/eigen.hpp>
#include <opencv2/imgcodecs.hpp>
#include <sstream>
#include <stdexcept>

#include "common/atomic_file.h"
#include "calib/circle_target.h"
#include "calib/epipolar.h"
#include "calib/fundamental.h"
#include "calib/target_file.h"
#include "common/input_limits.h"

namespace hnnstereo::calib {
namespace {

namespace fs = std::filesystem;

std::string Where(const std::string& path) { return TargetFileName(path); }

double ReadNumber(const cv::FileNode& node, const std::string& key, const std::string& path) {
  const cv::FileNode value = node[key];
  if (value.empty() || (!value.isReal() && !value.isInt())) {
    throw std::runtime_error(Where(path) + ": '" + key + "' is missing or not a number");
  }
  const double number = static_cast<double>(value);
  if (!std::isfinite(number)) {
    throw std::runtime_error(Where(path) + ": '" + key + "' is not finite");
  }
  return number;
}

// A circle grid larger than this is no target a camera resolves (1000 x 1000 circles at 4 px
// each already fill a 4000 x 4000 image).
constexpr int kMaxTargetRowsOrCols = 1000;

// A length in mm: finite (ReadNumber) and no larger than any cell.
double ReadLength(const cv::FileNode& node, const std::string& key, const std::string& path) {
  const double number = ReadNumber(node, key, path);
  if (std::abs(number) > TextInputLimits{}.max_abs_mm) {
    throw std::runtime_error(Where(path) + ": '" + key + "' is beyond +-1e7 mm");
  }
  return number;
}

std::string ResolveImage(const cv::FileNode& node, const std::string& key, const fs::path& dir,
                         const std::string& path, int index) {
  const cv::FileNode value = node[key];
  if (value.empty() || !value.isString()) {
    throw std::runtime_error(Where(path) + ": height " + std::to_string(index) + " has no '" + key +
                             "' image name");
  }
  const fs::path image = fs::path(static_cast<std::string>(value));
  const fs::path resolved = image.is_absolute() ? image : dir / image;
  if (!fs::is_regular_file(resolved)) {
    throw std::runtime_error(Where(path) + ": height " + std::to_string(index) + " " + key +
                             " image '" + resolved.string() + "' does not exist");
  }
  return resolved.string();
}

// Sum of per-view 12x12 normal matrices for a labeling, smallest eigenvalue and its vector.
double SmallestEigenvalue(const Eigen::Matrix<double, 12, 12>& M,
                          Eigen::Matrix<double, 12, 1>* vector = nullptr) {
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 12, 12>> solver(
      M, vector ? Eigen::ComputeEigenvectors : Eigen::EigenvaluesOnly);
  if (vector) *vector = solver.eigenvectors().col(0);
  return solver.eigenvalues()(0);
}

}  // namespace

std::string TargetDescription::Check() const {
  if (std::string problem = grid.Check(); !problem.empty()) return problem;
  if (placements.size() < 2) {
    return "the target must be seen at two or more heights (placements: " +
           std::to_string(placements.size()) + "); one plane is degenerate for the DLT";
  }
  for (size_t i = 0; i < placements.size(); ++i) {
    if (!placements[i].world_from_target.allFinite()) {
      return "height " + std::to_string(i) + ": world pose has non-finite values";
    }
    const Eigen::Matrix3d R = placements[i].world_from_target.block<3, 3>(0, 0);
    if ((R.transpose() * R - Eigen::Matrix3d::Identity()).norm() > 1e-6 || R.determinant() < 0) {
      return "height " + std::to_string(i) + ": world_from_target is not a rigid motion";
    }
  }
  return {};
}

std::string CircleCalibrationOptions::Check() const {
  if (std::string problem = detection.Check(); !problem.empty()) return problem;
  if (std::string problem = grid.Check(); !problem.empty()) return problem;
  return dlt.Check();
}

namespace {

// "height <index>" in an error about a placement of `path`.
std::string HeightWhere(const std::string& path, int index) {
  return Where(path) + ": height " + std::to_string(index);
}

// The grid's rows and cols (whole numbers in [2, kMaxTargetRowsOrCols]), pitch, circle radius
// (default 0.28 pitch) and circle polarity.
void ReadTargetGrid(const cv::FileNode& root, const std::string& path, TargetDescription* target) {
  // Range first: casting 1e12 to int is undefined, and rows x cols circles are searched for.
  for (const auto& [key, count] : {std::pair<const char*, int*>{"rows", &target->grid.rows},
                                   std::pair<const char*, int*>{"cols", &target->grid.cols}}) {
    const double value = ReadNumber(root, key, path);
    if (value < 2.0 || value > kMaxTargetRowsOrCols || value != std::floor(value)) {
      throw std::runtime_error(Where(path) + ": '" + key + "' must be a whole number in [2, " +
                               std::to_string(kMaxTargetRowsOrCols) + "] (is " +
                               std::to_string(value) + ")");
    }
    *count = static_cast<int>(value);
  }
  target->grid.pitch_mm = ReadLength(root, "pitch_mm", path);
  if (!root["circle_radius_mm"].empty()) {
    target->grid.circle_radius_mm = ReadLength(root, "circle_radius_mm", path);
  } else {
    target->grid.circle_radius_mm = 0.28 * target->grid.pitch_mm;
  }
  if (!root["dark_circles"].empty()) {
    target->dark_circles = ReadNumber(root, "dark_circles", path) != 0.0;
  }
}

// A placement's 4x4 world_from_target as written.
Eigen::Matrix4d ReadPoseMatrix(const cv::FileNode& height, const std::string& path, int index) {
  if (const std::string problem = CheckMatrixNode(height["world_from_target"], 16);
      !problem.empty()) {
    throw std::runtime_error(HeightWhere(path, index) + " world_from_target " + problem);
  }
  cv::Mat matrix;
  height["world_from_target"] >> matrix;
  if (matrix.total() != 16) {
    throw std::runtime_error(HeightWhere(path, index) + " world_from_target must be 4x4");
  }
  matrix = matrix.reshape(1, 4);
  matrix.convertTo(matrix, CV_64F);
  Eigen::Matrix4d pose;
  cv::cv2eigen(matrix, pose);
  return pose;
}

// A flat placement's pose from its origin_mm (3 numbers within +-1e7 mm) and yaw_deg (0 when
// absent): WorldFromTargetFlat.
Eigen::Matrix4d ReadFlatPose(const cv::FileNode& height, const std::string& path, int index) {
  std::vector<double> origin;
  if (height["origin_mm"].empty()) {
    throw std::runtime_error(HeightWhere(path, index) +
                             " needs 'origin_mm' (and 'yaw_deg') or 'world_from_target'");
  }
  if (const std::string problem = CheckMatrixNode(height["origin_mm"], 3); !problem.empty()) {
    throw std::runtime_error(HeightWhere(path, index) + " origin_mm " + problem);
  }
  height["origin_mm"] >> origin;
  if (origin.size() != 3) {
    throw std::runtime_error(HeightWhere(path, index) + " origin_mm must have 3 numbers");
  }
  for (double coordinate : origin) {
    if (!std::isfinite(coordinate) || std::abs(coordinate) > TextInputLimits{}.max_abs_mm) {
      throw std::runtime_error(HeightWhere(path, index) +
                               " origin_mm has a non-finite value or one beyond +-1e7 mm");
    }
  }
  const double yaw_deg = height["yaw_deg"].empty() ? 0.0 : ReadNumber(height, "yaw_deg", path);
  return WorldFromTargetFlat(Eigen::Vector3d(origin[0], origin[1], origin[2]), yaw_deg);
}

// One entry of 'heights': its two images (relative to the folder) and its pose, finite and
// within +-1e7 mm.
TargetPlacement ReadPlacement(const cv::FileNode& height, const fs::path& dir,
                              const std::string& path, int index) {
  if (!height.isMap()) throw std::runtime_error(HeightWhere(path, index) + " is not a map");
  TargetPlacement placement;
  placement.left_image = ResolveImage(height, "left", dir, path, index);
  placement.right_image = ResolveImage(height, "right", dir, path, index);
  placement.world_from_target = !height["world_from_target"].empty()
                                    ? ReadPoseMatrix(height, path, index)
                                    : ReadFlatPose(height, path, index);
  if (!placement.world_from_target.allFinite() ||
      placement.world_from_target.block<3, 1>(0, 3).cwiseAbs().maxCoeff() >
          TextInputLimits{}.max_abs_mm) {
    throw std::runtime_error(HeightWhere(path, index) +
                             " pose has a non-finite value or a translation beyond +-1e7 mm");
  }
  return placement;
}

// target.yml's text (size-limited and checked) parsed; throws on OpenCV's errors as ours.
TargetDescription ParseTargetYaml(const std::string& path, const fs::path& dir) {
  TargetDescription target;
  try {
    cv::FileStorage storage = OpenTargetFile(path);
    const cv::FileNode root = storage.root();
    ReadTargetGrid(root, path, &target);
    const cv::FileNode heights = root["heights"];
    if (heights.empty() || !heights.isSeq()) {
      throw std::runtime_error(Where(path) + ": 'heights' is missing or not a list");
    }
    int index = 0;
    for (cv::FileNodeIterator it = heights.begin(); it != heights.end(); ++it, ++index) {
      target.placements.push_back(ReadPlacement(*it, dir, path, index));
    }
  } catch (const cv::Exception& e) {
    throw std::runtime_error(Where(path) + " is not valid OpenCV YAML: " + e.err);
  }
  return target;
}

}  // namespace

TargetDescription LoadTargetDirectory(const std::string& target_dir) {
  const fs::path dir(target_dir);
  if (!fs::is_directory(dir)) {
    throw std::runtime_error("target folder '" + target_dir + "' does not exist");
  }
  const fs::path yml = dir / "target.yml";
  const std::string path = yml.string();
  if (!fs::is_regular_file(yml)) {
    throw std::runtime_error("target folder '" + target_dir + "' has no target.yml");
  }
  TargetDescription target = ParseTargetYaml(path, dir);
  if (const std::string problem = target.Check(); !problem.empty()) {
    throw std::runtime_error(Where(path) + ": " + problem);
  }
  return target;
}

void SaveTargetDescription(const TargetDescription& target, const std::string& path,
                           const std::function<void(cv::FileStorage*)>& more_keys) {
  WriteAtomically(path, [&](const std::string& temporary) {
    cv::FileStorage storage(temporary, cv::FileStorage::WRITE | cv::FileStorage::FORMAT_YAML);
    if (!storage.isOpened()) throw std::runtime_error("cannot open '" + path + "' for writing");
    storage << "rows" << target.grid.rows << "cols" << target.grid.cols;
    storage << "pitch_mm" << target.grid.pitch_mm;
    storage << "circle_radius_mm" << target.grid.circle_radius_mm;
    storage << "dark_circles" << static_cast<int>(target.dark_circles);
    storage << "heights"
            << "[";
    for (const TargetPlacement& placement : target.placements) {
      cv::Mat pose;
      cv::eigen2cv(placement.world_from_target, pose);
      storage << "{"
              << "left" << placement.left_image << "right" << placement.right_image
              << "world_from_target" << pose << "}";
    }
    storage << "]";
    if (more_keys) more_keys(&storage);
    storage.release();
  });
}

namespace {

using Matrix12d = Eigen::Matrix<double, 12, 12>;

// ChooseGridRotations' search over labelings (one grid rotation per view): the normalised DLT
// system of every view under every rotation, summed per labeling (H&Z algorithm 7.1).
class RotationSearch {
 public:
  RotationSearch(const std::vector<std::vector<Eigen::Vector3d>>& points3D_per_view,
                 const std::vector<std::vector<Eigen::Vector2d>>& centres_per_view,
                 const std::vector<std::vector<int>>& rotations)
      : points3D_(points3D_per_view), centres_(centres_per_view), rotations_(rotations),
        num_views_(points3D_per_view.size()), num_rotations_(rotations.size()) {
    Normalise();
    BuildNormalMatrices();
  }

  GridRotationChoice Run() const {
    const size_t num_seed = SeedViewCount();
    const std::vector<std::vector<int>> combos = ExtendSeeds(Seeds(num_seed), num_seed);
    const Scores scores = Score(combos);
    std::vector<size_t> equivalent;
    for (size_t c = 0; c < combos.size(); ++c) {
      if (scores.rms[c] <= 1.25 * scores.best_rms + 0.02) equivalent.push_back(c);
    }
    if (equivalent.empty()) {  // nothing cheiral: fall back to all labelings
      for (size_t c = 0; c < combos.size(); ++c) equivalent.push_back(c);
    }
    GridRotationChoice choice;
    choice.algebraic_residual = scores.best_algebraic;
    choice.reprojection_rms_px = scores.best_rms;
    choice.num_equivalent = static_cast<int>(equivalent.size());
    size_t chosen = equivalent.front();
    for (size_t c : equivalent) {
      if (scores.rms[c] < scores.rms[chosen]) chosen = c;
    }
    if (equivalent.size() > 1) {
      choice.decided_by_image_rule = true;
      chosen = ChooseByImageRule(equivalent, scores.cameras, chosen);
    }
    choice.rotation_per_view = combos[chosen];
    return choice;
  }

 private:
  // Each labeling's geometric reprojection RMS (px) of its linear DLT camera (+inf when not
  // cheiral), the cameras, and the best RMS with its algebraic residual.
  struct Scores {
    std::vector<double> rms;
    std::vector<ProjectionMatrix> cameras;
    double best_rms = std::numeric_limits<double>::infinity();
    double best_algebraic = std::numeric_limits<double>::infinity();
  };

  // One normalisation for all labelings: the point sets do not depend on the labeling.
  void Normalise() {
    for (size_t v = 0; v < num_views_; ++v) {
      all_world_.insert(all_world_.end(), points3D_[v].begin(), points3D_[v].end());
      all_image_.insert(all_image_.end(), centres_[v].begin(), centres_[v].end());
    }
    T_world_ = HartleyNormalisation3D(all_world_);
    T_image_ = HartleyNormalisation2D(all_image_);
    world_normalised_.resize(num_views_);
    for (size_t v = 0; v < num_views_; ++v) {
      for (const auto& X : points3D_[v]) world_normalised_[v].push_back(T_world_ * X.homogeneous());
    }
  }

  // normal_[v][r]: view v's DLT normal matrix with its centres turned by rotation r.
  void BuildNormalMatrices() {
    normal_.assign(num_views_, std::vector<Matrix12d>(num_rotations_));
    for (size_t v = 0; v < num_views_; ++v) {
      const auto& world = points3D_[v];
      const auto& centres = centres_[v];
      std::vector<Eigen::Vector3d> world_normalised;
      for (const auto& X : world) {
        world_normalised.push_back((T_world_ * X.homogeneous()).hnormalized());
      }
      for (size_t r = 0; r < num_rotations_; ++r) {
        std::vector<Eigen::Vector2d> image_normalised;
        for (size_t i = 0; i < world.size(); ++i) {
          image_normalised.push_back(
              (T_image_ * centres[static_cast<size_t>(rotations_[r][i])].homogeneous())
                  .hnormalized());
        }
        normal_[v][r] = DltNormalMatrix(world_normalised, image_normalised);
      }
    }
  }

  Matrix12d Summed(const std::vector<int>& combo) const {
    Matrix12d sum = Matrix12d::Zero();
    for (size_t v = 0; v < combo.size(); ++v) sum += normal_[v][static_cast<size_t>(combo[v])];
    return sum;
  }

  // The algebraic residual of a labeling, or +infinity when its DLT camera does not see all the
  // points on one side (cheirality, H&Z 6.2.3). Needed: with only two heights, turning one
  // height's labels by 180 degrees fits a projective camera exactly, one that has that height
  // behind it.
  double ResidualOf(const std::vector<int>& combo, Matrix12d* sum_out) const {
    const Matrix12d sum = Summed(combo);
    if (sum_out) *sum_out = sum;
    Eigen::Matrix<double, 12, 1> p;
    const double value = SmallestEigenvalue(sum, &p);
    const Eigen::Vector4d third_row = p.segment<4>(8);
    int positive = 0, negative = 0;
    for (size_t v = 0; v < combo.size(); ++v) {
      for (const Eigen::Vector4d& X : world_normalised_[v]) {
        (third_row.dot(X) > 0.0 ? positive : negative) += 1;
      }
    }
    return positive > 0 && negative > 0 ? std::numeric_limits<double>::infinity() : value;
  }

  // Whether the first `count` views' points span a volume (not one plane).
  bool SpansVolume(size_t count) const {
    std::vector<Eigen::Vector3d> points;
    for (size_t v = 0; v < count; ++v) {
      points.insert(points.end(), points3D_[v].begin(), points3D_[v].end());
    }
    Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
    for (const auto& X : points) centroid += X / static_cast<double>(points.size());
    Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
    for (const auto& X : points) scatter += (X - centroid) * (X - centroid).transpose();
    const Eigen::Vector3d spread =
        Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(scatter).eigenvalues();
    return spread(0) > 1e-6 * spread(2);
  }

  // Seed views: the first ones, enough to span more than one plane (a single plane leaves the
  // DLT degenerate for every labeling), at most 7 (4^7 = 16384 combinations).
  size_t SeedViewCount() const {
    size_t num_seed = std::min<size_t>(num_views_, 2);
    while (num_seed < num_views_ && num_seed < 7 && !SpansVolume(num_seed)) ++num_seed;
    return num_seed;
  }

  // Every labeling of the seed views (the first view's rotation counting fastest).
  std::vector<std::vector<int>> Seeds(size_t num_seed) const {
    std::vector<std::vector<int>> seeds;
    std::vector<int> combo(num_seed, 0);
    while (true) {
      seeds.push_back(combo);
      size_t k = 0;
      while (k < num_seed && ++combo[k] == static_cast<int>(num_rotations_)) combo[k++] = 0;
      if (k == num_seed) break;
    }
    return seeds;
  }

  // Extends every cheiral seed (all of them when none is) view by view: the rotation that keeps
  // the accumulated system most consistent (smallest eigenvalue) joins. The algebraic residual
  // is not invariant under the exact relabelings of two planes, so only the geometric error of
  // full labelings decides among them. Sorted, without duplicates.
  std::vector<std::vector<int>> ExtendSeeds(const std::vector<std::vector<int>>& seeds,
                                            size_t num_seed) const {
    std::vector<double> seed_residuals(seeds.size());
    double best_seed = std::numeric_limits<double>::infinity();
    for (size_t c = 0; c < seeds.size(); ++c) {
      Matrix12d sum;
      seed_residuals[c] = ResidualOf(seeds[c], &sum);
      best_seed = std::min(best_seed, seed_residuals[c]);
    }
    std::vector<std::vector<int>> combos;
    for (size_t c = 0; c < seeds.size(); ++c) {
      if (!std::isfinite(seed_residuals[c]) && std::isfinite(best_seed)) continue;
      std::vector<int> combo = seeds[c];
      Matrix12d sum = Summed(combo);
      for (size_t v = num_seed; v < num_views_; ++v) {
        double best = std::numeric_limits<double>::infinity();
        int best_rotation = 0;
        for (size_t r = 0; r < num_rotations_; ++r) {
          const double value = SmallestEigenvalue(sum + normal_[v][r]);
          if (value < best) {
            best = value;
            best_rotation = static_cast<int>(r);
          }
        }
        combo.push_back(best_rotation);
        sum += normal_[v][static_cast<size_t>(best_rotation)];
      }
      combos.push_back(combo);
    }
    std::sort(combos.begin(), combos.end());
    combos.erase(std::unique(combos.begin(), combos.end()), combos.end());
    return combos;
  }

  Scores Score(const std::vector<std::vector<int>>& combos) const {
    Scores scores;
    scores.rms.resize(combos.size());
    scores.cameras.resize(combos.size());
    for (size_t c = 0; c < combos.size(); ++c) {
      Matrix12d sum;
      const double algebraic = ResidualOf(combos[c], &sum);
      Eigen::Matrix<double, 12, 1> p;
      SmallestEigenvalue(sum, &p);
      ProjectionMatrix P_normalised;
      for (int row = 0; row < 3; ++row) {
        for (int col = 0; col < 4; ++col) P_normalised(row, col) = p(4 * row + col);
      }
      scores.cameras[c] = T_image_.inverse() * P_normalised * T_world_;
      double sum_sq = 0.0;
      size_t count = 0;
      for (size_t v = 0; v < num_views_; ++v) {
        const std::vector<int>& rotation = rotations_[static_cast<size_t>(combos[c][v])];
        for (size_t i = 0; i < points3D_[v].size(); ++i) {
          const Eigen::Vector2d& measured = centres_[v][static_cast<size_t>(rotation[i])];
          sum_sq += (Project(scores.cameras[c], points3D_[v][i]) - measured).squaredNorm();
          ++count;
        }
      }
      scores.rms[c] = std::isfinite(algebraic) ? std::sqrt(sum_sq / static_cast<double>(count))
                                               : std::numeric_limits<double>::infinity();
      if (scores.rms[c] < scores.best_rms) {
        scores.best_rms = scores.rms[c];
        scores.best_algebraic = algebraic;
      }
    }
    return scores;
  }

  // Orientation rule among equally good labelings: world +X appears closest to image +u
  // (`chosen` when no alignment is a number).
  size_t ChooseByImageRule(const std::vector<size_t>& equivalent,
                           const std::vector<ProjectionMatrix>& cameras, size_t chosen) const {
    Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
    for (const auto& X : all_world_) centroid += X;
    centroid /= static_cast<double>(all_world_.size());
    double best_alignment = -std::numeric_limits<double>::infinity();
    for (size_t c : equivalent) {
      const Eigen::Vector2d direction =
          Project(cameras[c], centroid + Eigen::Vector3d::UnitX()) - Project(cameras[c], centroid);
      const double alignment = direction.x() / std::max(direction.norm(), 1e-300);
      if (alignment > best_alignment) {
        best_alignment = alignment;
        chosen = c;
      }
    }
    return chosen;
  }

  const std::vector<std::vector<Eigen::Vector3d>>& points3D_;
  const std::vector<std::vector<Eigen::Vector2d>>& centres_;
  const std::vector<std::vector<int>>& rotations_;
  const size_t num_views_, num_rotations_;
  std::vector<Eigen::Vector3d> all_world_;
  std::vector<Eigen::Vector2d> all_image_;
  Eigen::Matrix4d T_world_;
  Eigen::Matrix3d T_image_;
  std::vector<std::vector<Eigen::Vector4d>> world_normalised_;  // T_world X, per view
  std::vector<std::vector<Matrix12d>> normal_;
};

}  // namespace

GridRotationChoice ChooseGridRotations(
    const std::vector<std::vector<Eigen::Vector3d>>& points3D_per_view,
    const std::vector<std::vector<Eigen::Vector2d>>& canonical_centres_per_view,
    const std::vector<std::vector<int>>& rotations) {
  const size_t num_views = points3D_per_view.size();
  if (num_views == 0 || canonical_centres_per_view.size() != num_views || rotations.empty()) {
    throw std::invalid_argument("ChooseGridRotations: inconsistent input sizes");
  }
  return RotationSearch(points3D_per_view, canonical_centres_per_view, rotations).Run();
}

CalibrationResult CalibrateFromCorrespondences(
    const std::string& method, const std::vector<std::vector<Eigen::Vector3d>>& left_world,
    const std::vector<std::vector<Eigen::Vector2d>>& left_image,
    const std::vector<std::vector<Eigen::Vector3d>>& right_world,
    const std::vector<std::vector<Eigen::Vector2d>>& right_image, const DltOptions& options) {
  CalibrationResult result;
  result.report.method = method;
  result.report.num_views = static_cast<int>(std::max(left_world.size(), right_world.size()));
  const std::vector<std::vector<Eigen::Vector3d>>* worlds[2] = {&left_world, &right_world};
  const std::vector<std::vector<Eigen::Vector2d>>* images[2] = {&left_image, &right_image};
  const char* names[2] = {"left", "right"};
  for (int camera = 0; camera < 2; ++camera) {
    std::vector<Eigen::Vector3d> world;
    std::vector<Eigen::Vector2d> image;
    CameraCalibrationReport camera_report;
    camera_report.camera = names[camera];
    for (size_t v = 0; v < worlds[camera]->size(); ++v) {
      const auto& view_world = (*worlds[camera])[v];
      const auto& view_image = (*images[camera])[v];
      for (size_t i = 0; i < view_world.size(); ++i) {
        world.push_back(view_world[i]);
        image.push_back(view_image[i]);
        CalibrationObservation observation;
        observation.point3D_in_world = view_world[i];
        observation.measured_px = view_image[i];
        observation.view = static_cast<int>(v);
        observation.label = std::string("p").append(std::to_string(i));
        camera_report.observations.push_back(observation);
      }
    }
    DltReport dlt;
    try {
      dlt = EstimateProjectionDlt(world, image, options);
    } catch (const std::invalid_argument& e) {
      throw std::runtime_error(std::string(names[camera]) + " camera: " + e.what());
    }
    (camera == 0 ? result.calibration.P1 : result.calibration.P2) = dlt.P;
    camera_report.linear = dlt.linear;
    camera_report.final = dlt.final;
    camera_report.refined = dlt.refined;
    camera_report.camera_centre = dlt.camera_centre;
    for (auto& observation : camera_report.observations) {
      observation.reprojected_px = Project(dlt.P, observation.point3D_in_world);
    }
    result.report.cameras.push_back(std::move(camera_report));
  }
  result.calibration.DeriveFromProjections();
  // Epipolar consistency over points measured in both cameras (same view, same world point).
  std::vector<Eigen::Vector2d> left_points, right_points;
  const auto& left_obs = result.report.cameras[0].observations;
  const auto& right_obs = result.report.cameras[1].observations;
  for (const auto& l : left_obs) {
    for (const auto& r : right_obs) {
      if (l.view == r.view && (l.point3D_in_world - r.point3D_in_world).norm() < 1e-9) {
        left_points.push_back(l.measured_px);
        right_points.push_back(r.measured_px);
        break;
      }
    }
  }
  result.report.num_epipolar_pairs = static_cast<int>(left_points.size());
  result.report.mean_epipolar_distance_px =
      MeanEpipolarDistancePx(result.calibration.F, left_points, right_points);
  StoreErrorFigures(&result);
  return result;
}

TargetImages LoadTargetImages(const std::string& target_dir) {
  TargetImages loaded;
  loaded.target = LoadTargetDirectory(target_dir);
  const char* names[2] = {"left", "right"};
  for (const TargetPlacement& placement : loaded.target.placements) {
    for (int camera = 0; camera < 2; ++camera) {
      const std::string& path = camera == 0 ? placement.left_image : placement.right_image;
      std::vector<cv::Mat>& images = camera == 0 ? loaded.left : loaded.right;
      const cv::Mat image = ReadImageFileWithin(path, cv::IMREAD_GRAYSCALE);  // size-checked first
      if (!images.empty() && image.size() != images.front().size()) {
        throw std::runtime_error("image '" + path + "' differs in size from the " + names[camera] +
                                 " image of height 0");
      }
      images.push_back(image);
    }
  }
  return loaded;
}

CalibrationResult CalibrateCircleTarget(const std::string& target_dir,
                                        const CircleCalibrationOptions& options) {
  if (const std::string problem = options.Check(); !problem.empty()) {
    throw std::runtime_error(problem);
  }
  return CalibrateCircleTarget(LoadTargetImages(target_dir), options);
}

CalibrationResult CalibrateCircleTarget(const TargetImages& images,
                                        const CircleCalibrationOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  if (const std::string problem = options.Check(); !problem.empty()) {
    throw std::runtime_error(problem);
  }
  const TargetDescription& target = images.target;
  CircleDetectionOptions detection_options = options.detection;
  detection_options.dark_circles = target.dark_circles;
  const std::vector<std::vector<int>> rotations = GridRotations(target.grid.rows, target.grid.cols);
  const size_t num_views = target.placements.size();
  if (num_views == 0 || images.left.size() != num_views || images.right.size() != num_views) {
    throw std::invalid_argument("CalibrateCircleTarget: one left and one right image per height, "
                                "at least one height");
  }

  std::vector<std::vector<Eigen::Vector3d>> world(num_views);
  std::vector<std::vector<Eigen::Vector2d>> centres[2];
  const char* names[2] = {"left", "right"};
  for (size_t v = 0; v < num_views; ++v) {
    const TargetPlacement& placement = target.placements[v];
    world[v] = target.grid.PointsInWorld(placement.world_from_target);
    for (int camera = 0; camera < 2; ++camera) {
      const std::string& path = camera == 0 ? placement.left_image : placement.right_image;
      const cv::Mat& image = camera == 0 ? images.left[v] : images.right[v];
      const CircleGridDetection detection =
          DetectCircleGrid(image, target.grid, detection_options, options.grid);
      if (!detection.found) {
        throw std::runtime_error("height " + std::to_string(v) + ", " + names[camera] + " image '" +
                                 path + "': " + detection.message);
      }
      centres[camera].push_back(detection.centres_px);
    }
  }
  // Rotation of the symmetric grid per height and camera, from the world poses.
  std::vector<std::vector<Eigen::Vector2d>> ordered[2];
  std::vector<std::string> notes;
  for (int camera = 0; camera < 2; ++camera) {
    const GridRotationChoice choice = ChooseGridRotations(world, centres[camera], rotations);
    for (size_t v = 0; v < num_views; ++v) {
      const std::vector<int>& rotation =
          rotations[static_cast<size_t>(choice.rotation_per_view[v])];
      std::vector<Eigen::Vector2d> view_centres(rotation.size());
      for (size_t i = 0; i < rotation.size(); ++i) {
        view_centres[i] = centres[camera][v][static_cast<size_t>(rotation[i])];
      }
      ordered[camera].push_back(view_centres);
    }
    if (choice.decided_by_image_rule) {
      notes.push_back(std::string(names[camera]) + " camera: the world poses fit " +
                      std::to_string(choice.num_equivalent) +
                      " grid orientations equally well; chose the one that shows world +X "
                      "closest to image +u (rightward)");
    }
  }
  CalibrationResult result =
      CalibrateFromCorrespondences("circles", world, ordered[0], world, ordered[1], options.dlt);
  result.calibration.image_width = images.left.front().cols;
  result.calibration.image_height = images.left.front().rows;
  result.report.notes = notes;
  const int cols = target.grid.cols;
  for (int camera = 0; camera < 2; ++camera) {
    CameraCalibrationReport& camera_report = result.report.cameras[static_cast<size_t>(camera)];
    for (auto& observation : camera_report.observations) {
      const int index = std::stoi(observation.label.substr(1));
      observation.label = std::string("r")
                              .append(std::to_string(index / cols))
                              .append("c")
                              .append(std::to_string(index % cols));
    }
    camera_report.overlay = DrawCalibrationOverlay(camera == 0 ? images.left.front()
                                                               : images.right.front(),
                                                   camera_report.observations);
  }
  result.report.extra["grid"] = {
      {"rows", target.grid.rows}, {"cols", target.grid.cols}, {"pitch_mm", target.grid.pitch_mm}};
  result.report.elapsed_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  return result;
}

}  // namespace hnnstereo::calib
