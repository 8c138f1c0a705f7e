#include "calib/circle_target.h"

#include <Eigen/Geometry>
#include <Eigen/LU>
#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <numeric>
#include <opencv2/imgproc.hpp>
#include <sstream>
#include <stdexcept>

#include "calib/dlt.h"

namespace hnnstereo::calib {
namespace {

double Cross(const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  return a.x() * b.y() - a.y() * b.x();
}

// Homography H with dst ~ H src from 4 points exactly (8x8 linear system, h33 = 1).
bool HomographyFromFour(const Eigen::Vector2d src[4], const Eigen::Vector2d dst[4],
                        Eigen::Matrix3d* H) {
  Eigen::Matrix<double, 8, 8> A;
  Eigen::Matrix<double, 8, 1> b;
  for (int i = 0; i < 4; ++i) {
    const double x = src[i].x(), y = src[i].y(), u = dst[i].x(), v = dst[i].y();
    A.row(2 * i) << x, y, 1, 0, 0, 0, -u * x, -u * y;
    A.row(2 * i + 1) << 0, 0, 0, x, y, 1, -v * x, -v * y;
    b(2 * i) = u;
    b(2 * i + 1) = v;
  }
  const Eigen::FullPivLU<Eigen::Matrix<double, 8, 8>> lu(A);
  if (!lu.isInvertible()) return false;
  const Eigen::Matrix<double, 8, 1> h = lu.solve(b);
  *H << h(0), h(1), h(2), h(3), h(4), h(5), h(6), h(7), 1.0;
  return H->allFinite();
}

// Least-squares homography (normalised DLT, H&Z algorithm 4.2).
Eigen::Matrix3d HomographyLeastSquares(const std::vector<Eigen::Vector2d>& src,
                                       const std::vector<Eigen::Vector2d>& dst) {
  const Eigen::Matrix3d T_src = HartleyNormalisation2D(src);
  const Eigen::Matrix3d T_dst = HartleyNormalisation2D(dst);
  Eigen::MatrixXd A(2 * static_cast<Eigen::Index>(src.size()), 9);
  for (size_t i = 0; i < src.size(); ++i) {
    const Eigen::Vector3d x = T_src * src[i].homogeneous();
    const Eigen::Vector3d y = T_dst * dst[i].homogeneous();
    const auto r = static_cast<Eigen::Index>(2 * i);
    A.row(r) << x.transpose(), 0, 0, 0, -y.x() * x.transpose();
    A.row(r + 1) << 0, 0, 0, x.transpose(), -y.y() * x.transpose();
  }
  Eigen::JacobiSVD<Eigen::MatrixXd> svd(A, Eigen::ComputeFullV);
  const Eigen::Matrix<double, 9, 1> h = svd.matrixV().col(8);
  Eigen::Matrix3d H;
  H << h(0), h(1), h(2), h(3), h(4), h(5), h(6), h(7), h(8);
  return T_dst.inverse() * H * T_src;
}

Eigen::Vector2d Apply(const Eigen::Matrix3d& H, double x, double y) {
  return (H * Eigen::Vector3d(x, y, 1.0)).hnormalized();
}

// Sub-pixel centre: centroid with area-coverage weights w = (I_out - I) / (I_out - I_in) clamped
// to [0, 1] over the blob grown by 2 px (unbiased for a symmetric blur of the edge).
Eigen::Vector2d WeightedCentre(const cv::Mat& grey, const std::vector<cv::Point>& contour,
                               bool dark_circles, const Eigen::Vector2d& binary_centre) {
  constexpr int kPad = 5;
  const cv::Rect bounds = cv::boundingRect(contour);
  const cv::Rect roi = cv::Rect(bounds.x - kPad, bounds.y - kPad, bounds.width + 2 * kPad,
                                bounds.height + 2 * kPad) &
                       cv::Rect(0, 0, grey.cols, grey.rows);
  cv::Mat mask = cv::Mat::zeros(roi.size(), CV_8U);
  cv::drawContours(mask, std::vector<std::vector<cv::Point>>{contour}, 0, cv::Scalar(255),
                   cv::FILLED, cv::LINE_8, cv::noArray(), 0, cv::Point(-roi.x, -roi.y));
  const cv::Mat kernel = cv::getStructuringElement(cv::MORPH_RECT, cv::Size(3, 3));
  cv::Mat inner, support, outer_ring, grown1, grown4;
  cv::erode(mask, inner, kernel, cv::Point(-1, -1), 1);
  if (cv::countNonZero(inner) == 0) inner = mask;
  cv::dilate(mask, support, kernel, cv::Point(-1, -1), 2);
  cv::dilate(mask, grown1, kernel, cv::Point(-1, -1), 3);
  cv::dilate(mask, grown4, kernel, cv::Point(-1, -1), 5);
  outer_ring = grown4 & ~grown1;
  const cv::Mat patch = grey(roi);
  if (cv::countNonZero(outer_ring) == 0) return binary_centre;
  const double inside_grey = cv::mean(patch, inner)[0];
  const double outside_grey = cv::mean(patch, outer_ring)[0];
  const double contrast = dark_circles ? outside_grey - inside_grey : inside_grey - outside_grey;
  if (contrast < 10.0) return binary_centre;
  double sum_w = 0.0, sum_x = 0.0, sum_y = 0.0;
  for (int y = 0; y < patch.rows; ++y) {
    const uchar* pixel = patch.ptr<uchar>(y);
    const uchar* inside = support.ptr<uchar>(y);
    for (int x = 0; x < patch.cols; ++x) {
      if (!inside[x]) continue;
      const double level = pixel[x];
      double w =
          dark_circles ? (outside_grey - level) / contrast : (level - outside_grey) / contrast;
      w = std::clamp(w, 0.0, 1.0);
      sum_w += w;
      sum_x += w * (x + roi.x);
      sum_y += w * (y + roi.y);
    }
  }
  if (!(sum_w > 0.0)) return binary_centre;
  return {sum_x / sum_w, sum_y / sum_w};
}

}  // namespace

std::string CircleGridGeometry::Check() const {
  std::ostringstream out;
  if (rows < 2 || cols < 2) {
    out << "circle grid must have at least 2 rows and 2 columns (is " << rows << " x " << cols
        << ")";
  } else if (rows * cols < 6) {
    out << "circle grid needs at least 6 circles (is " << rows << " x " << cols << ")";
  } else if (!(pitch_mm > 0.0) || !std::isfinite(pitch_mm)) {
    out << "circle grid pitch_mm must be > 0 (is " << pitch_mm << ")";
  } else if (!(circle_radius_mm > 0.0) || circle_radius_mm >= 0.5 * pitch_mm) {
    out << "circle_radius_mm must be in (0, pitch_mm / 2) (is " << circle_radius_mm << ")";
  }
  return out.str();
}

std::vector<Eigen::Vector3d> CircleGridGeometry::PointsInWorld(
    const Eigen::Matrix4d& world_from_target) const {
  std::vector<Eigen::Vector3d> points;
  for (int r = 0; r < rows; ++r) {
    for (int c = 0; c < cols; ++c) {
      points.push_back((world_from_target * PointInTarget(r, c).homogeneous()).hnormalized());
    }
  }
  return points;
}

std::string CircleDetectionOptions::Check() const {
  std::ostringstream out;
  if (!(min_area_px > 0.0)) {
    out << "CircleDetectionOptions.min_area_px must be > 0 (is " << min_area_px << ")";
  } else if (!(max_area_fraction > 0.0 && max_area_fraction <= 1.0)) {
    out << "CircleDetectionOptions.max_area_fraction must be in (0, 1] (is " << max_area_fraction
        << ")";
  } else if (!(max_radial_deviation > 0.0)) {
    out << "CircleDetectionOptions.max_radial_deviation must be > 0 (is " << max_radial_deviation
        << ")";
  } else if (!(min_convexity >= 0.0 && min_convexity <= 1.0)) {
    out << "CircleDetectionOptions.min_convexity must be in [0, 1] (is " << min_convexity << ")";
  } else if (!std::isfinite(intermeans_offset)) {
    out << "CircleDetectionOptions.intermeans_offset must be finite";
  }
  return out.str();
}

std::string CircleGridOptions::Check() const {
  std::ostringstream out;
  if (max_candidates < 4) {
    out << "CircleGridOptions.max_candidates must be >= 4 (is " << max_candidates << ")";
  } else if (!(max_prediction_error > 0.0 && max_prediction_error < 0.5)) {
    out << "CircleGridOptions.max_prediction_error must be in (0, 0.5) (is " << max_prediction_error
        << ")";
  } else if (!(max_area_ratio >= 1.0)) {
    out << "CircleGridOptions.max_area_ratio must be >= 1 (is " << max_area_ratio << ")";
  }
  return out.str();
}

double ComputeThreshold(const cv::Mat& grey, const CircleDetectionOptions& options) {
  if (options.threshold == CircleDetectionOptions::Threshold::kOtsu) {
    cv::Mat ignored;
    return cv::threshold(grey, ignored, 0, 255, cv::THRESH_BINARY | cv::THRESH_OTSU);
  }
  // Iterative intermeans (Ridler & Calvard 1978): t = (mean below t + mean above t) / 2.
  cv::Mat histogram;
  const int channels[] = {0};
  const int bins[] = {256};
  const float range[] = {0.f, 256.f};
  const float* ranges[] = {range};
  cv::calcHist(&grey, 1, channels, cv::Mat(), histogram, 1, bins, ranges);
  double t = cv::mean(grey)[0];
  for (int iteration = 0; iteration < 100; ++iteration) {
    double n_low = 0, sum_low = 0, n_high = 0, sum_high = 0;
    for (int level = 0; level < 256; ++level) {
      const double count = histogram.at<float>(level);
      if (level <= t) {
        n_low += count;
        sum_low += count * level;
      } else {
        n_high += count;
        sum_high += count * level;
      }
    }
    if (n_low == 0 || n_high == 0) break;
    const double next = 0.5 * (sum_low / n_low + sum_high / n_high);
    const bool converged = std::abs(next - t) < 0.5;
    t = next;
    if (converged) break;
  }
  return std::clamp(t + options.intermeans_offset, 0.0, 255.0);
}

std::vector<CircleBlob> DetectCircleBlobs(const cv::Mat& image,
                                          const CircleDetectionOptions& options) {
  if (const std::string problem = options.Check(); !problem.empty()) {
    throw std::invalid_argument(problem);
  }
  if (image.empty()) throw std::invalid_argument("DetectCircleBlobs: empty image");
  cv::Mat grey;
  if (image.channels() == 3) {
    cv::cvtColor(image, grey, cv::COLOR_BGR2GRAY);
  } else if (image.channels() == 4) {
    cv::cvtColor(image, grey, cv::COLOR_BGRA2GRAY);
  } else {
    grey = image;
  }
  if (grey.depth() != CV_8U) {
    cv::Mat converted;
    grey.convertTo(converted, CV_8U);
    grey = converted;
  }
  const double threshold = ComputeThreshold(grey, options);
  cv::Mat mask;
  cv::threshold(grey, mask, threshold, 255,
                options.dark_circles ? cv::THRESH_BINARY_INV : cv::THRESH_BINARY);

  // Border following (Suzuki & Abe 1985); outer borders only, so that the bright holes of dark
  // regions (reflections on the table) are never taken as circles.
  std::vector<std::vector<cv::Point>> contours;
  std::vector<cv::Vec4i> hierarchy;
  cv::findContours(mask, contours, hierarchy, cv::RETR_CCOMP, cv::CHAIN_APPROX_NONE);
  const double max_area = options.max_area_fraction * grey.rows * grey.cols;
  std::vector<CircleBlob> blobs;
  for (size_t i = 0; i < contours.size(); ++i) {
    if (hierarchy[i][3] >= 0) continue;  // a hole border
    const std::vector<cv::Point>& contour = contours[i];
    if (contour.size() < 8) continue;
    const cv::Moments moments = cv::moments(contour);
    const double area = moments.m00;
    if (area < options.min_area_px || area > max_area) continue;
    const Eigen::Vector2d centroid(moments.m10 / moments.m00, moments.m01 / moments.m00);
    // Thesis 3.2.4: normalised spread of the border-to-centroid distance.
    double sum = 0.0, sum_sq = 0.0;
    for (const cv::Point& p : contour) {
      const double r = (Eigen::Vector2d(p.x, p.y) - centroid).norm();
      sum += r;
      sum_sq += r * r;
    }
    const double n = static_cast<double>(contour.size());
    const double mean = sum / n;
    const double deviation = std::sqrt(std::max(0.0, sum_sq / n - mean * mean)) / mean;
    if (!(deviation <= options.max_radial_deviation)) continue;
    std::vector<cv::Point> hull;
    cv::convexHull(contour, hull);
    const double hull_area = cv::contourArea(hull);
    if (hull_area <= 0.0 || area / hull_area < options.min_convexity) continue;
    CircleBlob blob;
    blob.area_px = area;
    blob.radial_deviation = deviation;
    blob.centre_px = options.subpixel_centres
                         ? WeightedCentre(grey, contour, options.dark_circles, centroid)
                         : centroid;
    blobs.push_back(blob);
  }
  return blobs;
}

std::vector<std::vector<int>> GridRotations(int rows, int cols) {
  const int n = rows * cols;
  std::vector<int> identity(n);
  std::iota(identity.begin(), identity.end(), 0);
  std::vector<std::vector<int>> rotations = {identity};
  if (rows == cols) {
    // Rotation by 90 degrees: (row, col) <- (col, n - 1 - row); (x, y) -> (n-1-y, x), det +1.
    std::vector<int> current = identity;
    for (int k = 1; k < 4; ++k) {
      std::vector<int> next(n);
      for (int r = 0; r < rows; ++r) {
        for (int c = 0; c < cols; ++c) next[r * cols + c] = current[c * cols + (rows - 1 - r)];
      }
      rotations.push_back(next);
      current = next;
    }
  } else {
    std::vector<int> half_turn(n);
    for (int r = 0; r < rows; ++r) {
      for (int c = 0; c < cols; ++c)
        half_turn[r * cols + c] = (rows - 1 - r) * cols + (cols - 1 - c);
    }
    rotations.push_back(half_turn);
  }
  return rotations;
}

namespace {

// Blob indices, the most circular first, at most max_candidates of them.
std::vector<int> RankCandidates(const std::vector<CircleBlob>& blobs, int max_candidates) {
  std::vector<int> candidates(blobs.size());
  std::iota(candidates.begin(), candidates.end(), 0);
  std::stable_sort(candidates.begin(), candidates.end(), [&](int a, int b) {
    return blobs[a].radial_deviation < blobs[b].radial_deviation;
  });
  if (static_cast<int>(candidates.size()) > max_candidates) candidates.resize(max_candidates);
  return candidates;
}

// The best grid found so far: its fit residual (RMS over the mean blob spacing), blob per grid
// point (row-major) and least-squares homography from (col, row) to the image.
struct GridFit {
  double residual = std::numeric_limits<double>::infinity();
  std::vector<int> assignment;
  Eigen::Matrix3d H = Eigen::Matrix3d::Identity();
};

// The search for a rows x cols grid among the candidate blobs: every convex quad of candidates
// as the grid's corners, the rest predicted by the corner homography (thesis 3.2.4).
class GridSearch {
 public:
  GridSearch(const std::vector<CircleBlob>& blobs, std::vector<int> candidates, int rows,
             int cols, const CircleGridOptions& options)
      : blobs_(blobs), candidates_(std::move(candidates)), rows_(rows), cols_(cols),
        n_grid_(rows * cols), options_(options), assignment_(static_cast<size_t>(n_grid_)) {
    for (int r = 0; r < rows; ++r) {
      for (int c = 0; c < cols; ++c) grid_points_.emplace_back(c, r);
    }
  }

  GridFit Run() {
    const int m = static_cast<int>(candidates_.size());
    for (int a = 0; a < m; ++a) {
      for (int b = a + 1; b < m; ++b) {
        for (int c = b + 1; c < m; ++c) {
          for (int d = c + 1; d < m; ++d) {
            TryQuad(candidates_[a], candidates_[b], candidates_[c], candidates_[d]);
          }
        }
      }
    }
    return best_;
  }

 private:
  // The quad's blobs in cyclic order by angle about their centroid, when their areas agree
  // within max_area_ratio and they form a strictly convex quad; their area range in *min_area,
  // *max_area.
  bool OrderConvexQuad(int (&quad)[4], double* min_area, double* max_area) const {
    *min_area = std::numeric_limits<double>::infinity();
    *max_area = 0.0;
    Eigen::Vector2d centroid = Eigen::Vector2d::Zero();
    for (int q : quad) {
      *min_area = std::min(*min_area, blobs_[q].area_px);
      *max_area = std::max(*max_area, blobs_[q].area_px);
      centroid += 0.25 * blobs_[q].centre_px;
    }
    if (*max_area > options_.max_area_ratio * *min_area) return false;
    std::sort(quad, quad + 4, [&](int p, int q) {
      const Eigen::Vector2d dp = blobs_[p].centre_px - centroid;
      const Eigen::Vector2d dq = blobs_[q].centre_px - centroid;
      return std::atan2(dp.y(), dp.x()) < std::atan2(dq.y(), dq.x());
    });
    bool convex = true;
    for (int k = 0; k < 4 && convex; ++k) {
      const Eigen::Vector2d e1 = blobs_[quad[(k + 1) % 4]].centre_px - blobs_[quad[k]].centre_px;
      const Eigen::Vector2d e2 =
          blobs_[quad[(k + 2) % 4]].centre_px - blobs_[quad[(k + 1) % 4]].centre_px;
      convex = Cross(e1, e2) > 0.0;
    }
    return convex;
  }

  // Blobs a, b, c, d as the grid's corners (each of a rectangular grid's two orientations).
  void TryQuad(int a, int b, int c, int d) {
    int quad[4] = {a, b, c, d};
    double min_area = 0.0, max_area = 0.0;
    if (!OrderConvexQuad(quad, &min_area, &max_area)) return;
    const int starts = rows_ == cols_ ? 1 : 2;  // a square grid's corners are interchangeable
    for (int start = 0; start < starts; ++start) {
      if (!AssignGrid(quad, start, min_area, max_area)) continue;
      ScoreAssignment();
    }
  }

  // assignment_: quad[(start + k) % 4] at grid corner k, every other grid point the nearest
  // candidate to its prediction by the corner homography (within max_prediction_error of the
  // local spacing, unused, of an agreeing area). False when a point finds none.
  bool AssignGrid(const int (&quad)[4], int start, double min_area, double max_area) {
    const Eigen::Vector2d grid_corners[4] = {
        {0, 0}, {cols_ - 1.0, 0}, {cols_ - 1.0, rows_ - 1.0}, {0, rows_ - 1.0}};
    Eigen::Vector2d image_corners[4];
    for (int k = 0; k < 4; ++k) image_corners[k] = blobs_[quad[(start + k) % 4]].centre_px;
    Eigen::Matrix3d H;
    if (!HomographyFromFour(grid_corners, image_corners, &H)) return false;
    std::fill(assignment_.begin(), assignment_.end(), -1);
    for (int k = 0; k < 4; ++k) {
      const int index = static_cast<int>(grid_corners[k].y()) * cols_ +
                        static_cast<int>(grid_corners[k].x());
      assignment_[index] = quad[(start + k) % 4];
    }
    for (int i = 0; i < n_grid_; ++i) {
      if (assignment_[i] >= 0) continue;
      const int nearest = NearestToPrediction(H, grid_points_[i].x(), grid_points_[i].y());
      if (nearest < 0 ||
          std::find(assignment_.begin(), assignment_.end(), nearest) != assignment_.end()) {
        return false;
      }
      if (blobs_[nearest].area_px > options_.max_area_ratio * min_area ||
          max_area > options_.max_area_ratio * blobs_[nearest].area_px) {
        return false;
      }
      assignment_[i] = nearest;
    }
    return true;
  }

  // The candidate nearest to H's image of grid point (gx, gy), within max_prediction_error of
  // the predicted spacing there (the last of equally near ones); -1 when none is.
  int NearestToPrediction(const Eigen::Matrix3d& H, double gx, double gy) const {
    const Eigen::Vector2d predicted = Apply(H, gx, gy);
    const double spacing = std::min((Apply(H, gx + 1, gy) - predicted).norm(),
                                    (Apply(H, gx, gy + 1) - predicted).norm());
    const double tolerance = options_.max_prediction_error * spacing;
    int nearest = -1;
    double nearest_distance = tolerance;
    for (const int candidate : candidates_) {
      const double distance = (blobs_[candidate].centre_px - predicted).norm();
      if (distance <= nearest_distance) {
        nearest_distance = distance;
        nearest = candidate;
      }
    }
    return nearest;
  }

  // The mean distance between grid-neighbouring blobs: the residual's unit (not the fitted
  // homography's spacing, which a near-degenerate H makes huge, hiding its residual).
  double MeanBlobSpacing(const std::vector<Eigen::Vector2d>& image_points) const {
    double sum_spacing = 0.0;
    int num_spacings = 0;
    for (int r = 0; r < rows_; ++r) {
      for (int col = 0; col < cols_; ++col) {
        const Eigen::Vector2d& p = image_points[r * cols_ + col];
        if (col + 1 < cols_) sum_spacing += (image_points[r * cols_ + col + 1] - p).norm();
        if (r + 1 < rows_) sum_spacing += (image_points[(r + 1) * cols_ + col] - p).norm();
        num_spacings += (col + 1 < cols_) + (r + 1 < rows_);
      }
    }
    return sum_spacing / num_spacings;
  }

  // Fits a homography to assignment_ and keeps it when no point is off by more than
  // max_prediction_error spacings and its residual beats the best so far.
  void ScoreAssignment() {
    std::vector<Eigen::Vector2d> image_points(n_grid_);
    for (int i = 0; i < n_grid_; ++i) image_points[i] = blobs_[assignment_[i]].centre_px;
    const Eigen::Matrix3d H_fit = HomographyLeastSquares(grid_points_, image_points);
    const double mean_spacing = MeanBlobSpacing(image_points);
    double sum_sq = 0.0, worst = 0.0;
    for (int i = 0; i < n_grid_; ++i) {
      const double error =
          (Apply(H_fit, grid_points_[i].x(), grid_points_[i].y()) - image_points[i]).norm();
      sum_sq += error * error;
      worst = std::max(worst, error);
    }
    if (!H_fit.allFinite() || worst > options_.max_prediction_error * mean_spacing) return;
    const double residual = std::sqrt(sum_sq / n_grid_) / mean_spacing;
    if (residual < best_.residual) {
      best_.residual = residual;
      best_.assignment = assignment_;
      best_.H = H_fit;
    }
  }

  const std::vector<CircleBlob>& blobs_;
  const std::vector<int> candidates_;
  const int rows_, cols_, n_grid_;
  const CircleGridOptions& options_;
  std::vector<Eigen::Vector2d> grid_points_;  // (col, row) of every grid point, row-major
  std::vector<int> assignment_;               // the quad being tried
  GridFit best_;
};

// The canonical labeling of a found grid. Rule 1: handedness (target +z faces the camera,
// v points down); rule 2: the rotation whose +col direction is closest to image +u.
std::vector<int> CanonicalLabeling(const GridFit& fit, const std::vector<CircleBlob>& blobs,
                                   int rows, int cols) {
  const int n_grid = rows * cols;
  const double centre_col = 0.5 * (cols - 1), centre_row = 0.5 * (rows - 1);
  const Eigen::Vector2d origin = Apply(fit.H, centre_col, centre_row);
  const Eigen::Vector2d d_col = Apply(fit.H, centre_col + 1, centre_row) - origin;
  const Eigen::Vector2d d_row = Apply(fit.H, centre_col, centre_row + 1) - origin;
  std::vector<int> labeling = fit.assignment;
  if (Cross(d_col, d_row) > 0.0) {
    for (int r = 0; r < rows; ++r) {
      for (int c = 0; c < cols; ++c)
        labeling[r * cols + c] = fit.assignment[r * cols + (cols - 1 - c)];
    }
  }
  double best_alignment = -std::numeric_limits<double>::infinity();
  std::vector<int> canonical;
  for (const std::vector<int>& rotation : GridRotations(rows, cols)) {
    std::vector<int> rotated(n_grid);
    for (int i = 0; i < n_grid; ++i) rotated[i] = labeling[rotation[i]];
    Eigen::Vector2d col_direction = Eigen::Vector2d::Zero();
    for (int r = 0; r < rows; ++r) {
      col_direction +=
          blobs[rotated[r * cols + cols - 1]].centre_px - blobs[rotated[r * cols]].centre_px;
    }
    const double alignment = col_direction.x() / std::max(col_direction.norm(), 1e-12);
    if (alignment > best_alignment + 1e-9) {
      best_alignment = alignment;
      canonical = rotated;
    }
  }
  return canonical;
}

}  // namespace

CircleGridDetection FindCircleGrid(const std::vector<CircleBlob>& blobs,
                                   const CircleGridGeometry& grid,
                                   const CircleGridOptions& options) {
  if (const std::string problem = grid.Check(); !problem.empty()) {
    throw std::invalid_argument(problem);
  }
  if (const std::string problem = options.Check(); !problem.empty()) {
    throw std::invalid_argument(problem);
  }
  CircleGridDetection detection;
  detection.blobs = blobs;
  const int rows = grid.rows, cols = grid.cols, n_grid = grid.size();
  if (static_cast<int>(blobs.size()) < n_grid) {
    detection.message = "found " + std::to_string(blobs.size()) + " circular blobs, need " +
                        std::to_string(n_grid) + " for a " + std::to_string(rows) + " x " +
                        std::to_string(cols) + " grid";
    return detection;
  }
  const GridFit best =
      GridSearch(blobs, RankCandidates(blobs, options.max_candidates), rows, cols, options).Run();
  if (best.assignment.empty()) {
    detection.message = "no " + std::to_string(rows) + " x " + std::to_string(cols) +
                        " grid among " + std::to_string(blobs.size()) + " circular blobs";
    return detection;
  }
  const std::vector<int> canonical = CanonicalLabeling(best, blobs, rows, cols);
  detection.found = true;
  detection.grid_blob_index = canonical;
  for (int index : canonical) detection.centres_px.push_back(blobs[index].centre_px);
  detection.grid_fit_residual = best.residual;
  return detection;
}

CircleGridDetection DetectCircleGrid(const cv::Mat& image, const CircleGridGeometry& grid,
                                     const CircleDetectionOptions& detection_options,
                                     const CircleGridOptions& grid_options) {
  return FindCircleGrid(DetectCircleBlobs(image, detection_options), grid, grid_options);
}

Eigen::Matrix4d WorldFromTargetFlat(const Eigen::Vector3d& origin_mm, double yaw_deg) {
  Eigen::Matrix4d world_from_target = Eigen::Matrix4d::Identity();
  world_from_target.block<3, 3>(0, 0) =
      Eigen::AngleAxisd(yaw_deg * std::numbers::pi / 180.0, Eigen::Vector3d::UnitZ())
          .toRotationMatrix();
  world_from_target.block<3, 1>(0, 3) = origin_mm;
  return world_from_target;
}

}  // namespace hnnstereo::calib
