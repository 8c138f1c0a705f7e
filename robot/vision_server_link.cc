// PLACEHOLDER - being written (robot link issue); replaced by the real transport.
#include <stdexcept>

#include "robot/link.h"

namespace hnnstereo::robot {
std::unique_ptr<RobotLink> MakeVisionServerLink(const LinkUri& uri, SafetyGate, LinkOptions) {
  throw std::runtime_error(uri.scheme + ": transport not built yet");
}
}  // namespace hnnstereo::robot
