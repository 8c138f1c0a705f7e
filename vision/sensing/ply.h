#pragma once
// Point clouds as PLY (ASCII, x y z red green blue) for MeshLab/CloudCompare: the 3D view of the
// points the thesis drew.

#include <Eigen/Core>
#include <string>
#include <vector>

namespace hnnstereo::vision {

/// The PLY text of `points_in_world` (mm), each coloured by its label (LabelColour; -1 grey).
/// Throws std::invalid_argument when the sizes differ.
std::string PointCloudPly(const std::vector<Eigen::Vector3d>& points_in_world,
                          const std::vector<int>& labels);

/// Writes PointCloudPly atomically. Throws std::runtime_error naming the path on failure.
void WritePly(const std::string& path, const std::vector<Eigen::Vector3d>& points_in_world,
              const std::vector<int>& labels);

}  // namespace hnnstereo::vision
