#include "robot/vision_server_protocol.h"

#include <cmath>
#include <cstdio>

namespace hnnstereo::robot::vision_server {

Appended AppendReceived(std::string* input, const char* bytes, std::size_t count) {
  const auto old_newline = input->rfind('\n');
  const bool tail_was_empty =
      old_newline == std::string::npos ? input->empty() : old_newline + 1 == input->size();
  input->append(bytes, count);
  // Only the unterminated tail counts against the line limit.
  const auto newline = input->rfind('\n');
  Appended appended;
  appended.tail = newline == std::string::npos ? input->size() : input->size() - newline - 1;
  appended.tail_started = tail_was_empty && appended.tail > 0;
  return appended;
}

bool HasCompleteLine(const std::string& input) { return input.find('\n') != std::string::npos; }

std::string TakeLine(std::string* input) {
  const auto newline = input->find('\n');
  std::string line = input->substr(0, newline);
  input->erase(0, newline + 1);
  const auto first = line.find_first_not_of(" \t\r");
  const auto last = line.find_last_not_of(" \t\r");
  return first == std::string::npos ? std::string() : line.substr(first, last - first + 1);
}

Request ParseRequest(const std::string& line) {
  if (line == "TRIG") return Request::kTrigger;
  if (line == "NEXT") return Request::kNext;
  if (line == "STOP") return Request::kStop;
  return Request::kMalformed;
}

std::string Printable(const std::string& text) {
  std::string shown;
  for (char c : text.substr(0, 40)) shown += (c >= 32 && c < 127) ? c : '?';
  return text.size() > 40 ? shown + "..." : shown;
}

std::string ReplyLine(int status, const PickCommand* pick) {
  double v[6] = {0, 0, 0, 0, 0, 0};
  if (pick != nullptr) {
    const Eigen::AngleAxisd rotation(pick->orientation.normalized());
    const Eigen::Vector3d rotation_vector = rotation.axis() * rotation.angle();
    for (int i = 0; i < 3; ++i) {
      v[i] = pick->position_mm[i] / 1000.0;
      v[3 + i] = rotation_vector[i];
    }
  }
  for (double& value : v) {
    if (std::abs(value) < 5e-7) value = 0.0;  // never print "-0.000000"
  }
  char text[160];
  std::snprintf(text, sizeof text, "(%d,%.6f,%.6f,%.6f,%.6f,%.6f,%.6f)\n", status, v[0], v[1],
                v[2], v[3], v[4], v[5]);
  return text;
}

}  // namespace hnnstereo::robot::vision_server
