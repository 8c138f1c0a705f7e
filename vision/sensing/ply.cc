#include "vision/sensing/ply.h"

#include <sstream>
#include <stdexcept>

#include "common/atomic_file.h"
#include "vision/sensing/plots.h"

namespace hnnstereo::vision {

std::string PointCloudPly(const std::vector<Eigen::Vector3d>& points_in_world,
                          const std::vector<int>& labels) {
  if (labels.size() != points_in_world.size()) {
    throw std::invalid_argument("PointCloudPly: " + std::to_string(points_in_world.size()) +
                                " points but " + std::to_string(labels.size()) + " labels");
  }
  std::ostringstream out;
  out << "ply\nformat ascii 1.0\ncomment hnnstereo triangulated points, mm, world frame\n"
      << "element vertex " << points_in_world.size() << "\n"
      << "property float x\nproperty float y\nproperty float z\n"
      << "property uchar red\nproperty uchar green\nproperty uchar blue\nend_header\n";
  for (std::size_t i = 0; i < points_in_world.size(); ++i) {
    const cv::Scalar bgr = LabelColour(labels[i]);
    const Eigen::Vector3d& p = points_in_world[i];
    out << p.x() << ' ' << p.y() << ' ' << p.z() << ' ' << static_cast<int>(bgr[2]) << ' '
        << static_cast<int>(bgr[1]) << ' ' << static_cast<int>(bgr[0]) << '\n';
  }
  return out.str();
}

void WritePly(const std::string& path, const std::vector<Eigen::Vector3d>& points_in_world,
              const std::vector<int>& labels) {
  calib::WriteFileAtomically(path, PointCloudPly(points_in_world, labels));
}

}  // namespace hnnstereo::vision
