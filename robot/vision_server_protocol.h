#pragma once
// The ASCII protocol of the vision-server transport without the sockets (vision-server,
// robot/vision_server_link.cc; docs/robot_ascii.md): the bytes a client sent become lines,
// lines become requests (TRIG, NEXT, STOP or malformed), and replies are one line
// `(st,x,y,z,rx,ry,rz)\n`. Pure: no I/O, no clock. Fuzzed by fuzz/fuzz_vision_server_line.cc.

#include <cstddef>
#include <string>

#include "robot/pick_command.h"

namespace hnnstereo::robot::vision_server {

enum class Request { kTrigger, kNext, kStop, kMalformed };

/// What appending received bytes did to a connection's input.
struct Appended {
  std::size_t tail = 0;       ///< bytes after the last newline (the unterminated request)
  bool tail_started = false;  ///< the input ended in a whole line (or was empty) before, not now
};
/// Appends `count` received bytes to `input`. A tail longer than the line limit
/// (ServerLimits::max_line_bytes) is the caller's to refuse.
Appended AppendReceived(std::string* input, const char* bytes, std::size_t count);

/// True when `input` holds a whole request (a newline).
bool HasCompleteLine(const std::string& input);

/// Takes the first whole request off `input` (HasCompleteLine must hold), trimmed of spaces,
/// tabs and the CR a URScript `socket_send_line` may add.
std::string TakeLine(std::string* input);

/// TRIG, NEXT and STOP; anything else is malformed.
Request ParseRequest(const std::string& line);

/// At most 40 characters of `text` for a log line, non-printable bytes as '?', "..." when cut.
std::string Printable(const std::string& text);

/// One reply line: `(st,x,y,z,rx,ry,rz)\n`, metres and radians (UR pose); zeros without a pick.
std::string ReplyLine(int status, const PickCommand* pick);

}  // namespace hnnstereo::robot::vision_server
