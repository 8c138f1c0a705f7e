#include "robot/link.h"

#include <charconv>
#include <iostream>
#include <stdexcept>

#include "robot/modbus_registers.h"

namespace hnnstereo::robot {

int PublishedStatusCode(int cycle_status) {
  return cycle_status < 0 ? cycle_status : modbus::kStatusResultReady;
}
namespace {

// Servers may ask for port 0 (any free port; Describe() then names the port bound).
int ParsePort(const std::string& text, const std::string& uri, bool zero_allowed) {
  int port = 0;
  const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), port);
  const int lowest = zero_allowed ? 0 : 1;
  if (error != std::errc() || end != text.data() + text.size() || port < lowest || port > 65535) {
    throw std::invalid_argument("robot URI '" + uri + "': port '" + text +
                                "' is not a number in " + std::to_string(lowest) + "..65535");
  }
  return port;
}

}  // namespace

LinkUri ParseLinkUri(const std::string& uri) {
  LinkUri parsed;
  parsed.text = uri;
  const auto colon = uri.find(':');
  if (colon == std::string::npos || colon == 0) {
    throw std::invalid_argument("robot URI '" + uri +
                                "' has no scheme (dryrun:FILE.jsonl, modbus-server://HOST:PORT, "
                                "modbus-client://HOST:PORT, vision-server://HOST:PORT, "
                                "serial:DEVICE?baud=2400)");
  }
  parsed.scheme = uri.substr(0, colon);
  std::string rest = uri.substr(colon + 1);
  if (const auto question = rest.find('?'); question != std::string::npos) {
    const std::string query = rest.substr(question + 1);
    rest = rest.substr(0, question);
    std::size_t start = 0;
    while (start <= query.size()) {
      const auto amp = query.find('&', start);
      const std::string item =
          query.substr(start, amp == std::string::npos ? std::string::npos : amp - start);
      const auto eq = item.find('=');
      if (item.empty() || eq == std::string::npos || eq == 0) {
        throw std::invalid_argument("robot URI '" + uri + "': query item '" + item +
                                    "' is not key=value");
      }
      parsed.query[item.substr(0, eq)] = item.substr(eq + 1);
      if (amp == std::string::npos) break;
      start = amp + 1;
    }
  }
  const bool network = parsed.scheme == "modbus-server" || parsed.scheme == "modbus-client" ||
                       parsed.scheme == "vision-server";
  if (network) {
    if (rest.rfind("//", 0) != 0) {
      throw std::invalid_argument("robot URI '" + uri + "': expected " + parsed.scheme +
                                  "://HOST:PORT");
    }
    rest = rest.substr(2);
    const auto port_colon = rest.rfind(':');
    if (port_colon == std::string::npos || port_colon == 0) {
      throw std::invalid_argument("robot URI '" + uri + "': expected " + parsed.scheme +
                                  "://HOST:PORT");
    }
    parsed.host = rest.substr(0, port_colon);
    parsed.port =
        ParsePort(rest.substr(port_colon + 1), uri, parsed.scheme != "modbus-client");
  } else if (parsed.scheme == "dryrun" || parsed.scheme == "serial") {
    if (rest.rfind("//", 0) == 0) rest = rest.substr(2);
    if (rest.empty()) {
      throw std::invalid_argument("robot URI '" + uri + "': " + parsed.scheme + " needs a " +
                                  (parsed.scheme == "dryrun" ? "file (dryrun:picks.jsonl)"
                                                             : "device (serial:/dev/ttyUSB0)"));
    }
    parsed.path = rest;
  } else {
    throw std::invalid_argument("robot URI '" + uri + "': unknown scheme '" + parsed.scheme +
                                "' (dryrun, modbus-server, modbus-client, vision-server, serial)");
  }
  return parsed;
}

std::string LinkOptions::Check() const {
  if (io_timeout.count() <= 0) return "io_timeout must be positive";
  if (heartbeat_period.count() <= 0) return "heartbeat_period must be positive";
  if (reconnect_backoff_min.count() <= 0 || reconnect_backoff_max < reconnect_backoff_min) {
    return "reconnect backoff must satisfy 0 < min <= max";
  }
  if (max_poses < 1 || max_poses > 64) return "max_poses must be in 1..64";
  return server.Check();
}

std::string ServerLimits::Check() const {
  if (max_connections < 1) return "server max_connections must be at least 1";
  if (max_connections_per_peer < 1 || max_connections_per_peer > max_connections) {
    return "server max_connections_per_peer must be in 1..max_connections";
  }
  if (first_request_timeout.count() <= 0) return "server first_request_timeout must be positive";
  if (max_requests_per_second < 1 || request_burst < 1) {
    return "server max_requests_per_second and request_burst must be at least 1";
  }
  if (max_line_bytes < 16) return "server max_line_bytes must be >= 16";
  return {};
}

const char* CellCommandName(CellCommand command) {
  switch (command) {
    case CellCommand::kHome: return "home";
    case CellCommand::kOpen: return "open";
    case CellCommand::kClose: return "close";
    case CellCommand::kStop: return "stop";
  }
  return "?";
}

RobotLink::RobotLink(SafetyGate gate, LinkOptions options)
    : gate_(std::move(gate)), options_(std::move(options)) {
  if (auto error = options_.Check(); !error.empty()) throw std::invalid_argument(error);
}

void RobotLink::Log(const std::string& line) const {
  if (options_.log) {
    options_.log(line);
  } else {
    std::cerr << "hnnstereo: robot: " << line << "\n";
  }
}

PublishReport RobotLink::Publish(CycleResult cycle) {
  PublishReport report;
  std::vector<PickCommand> admitted;
  for (PickCommand& pick : cycle.picks) {
    if (auto refusal = gate_.Admit(&pick)) {
      report.outcomes.push_back({pick.object_id, pick.sequence, false, *refusal});
      ++report.refused;
      report.refusals.push_back("object " + std::to_string(pick.object_id) + " (sequence " +
                                std::to_string(pick.sequence) + ") refused: " + *refusal);
      Log(report.refusals.back());
    } else if (static_cast<int>(admitted.size()) < options_.max_poses) {
      report.outcomes.push_back({pick.object_id, pick.sequence, true, ""});
      admitted.push_back(pick);
    } else {
      report.outcomes.push_back({pick.object_id, pick.sequence, false,
                                 "more than max_poses " + std::to_string(options_.max_poses) +
                                     " in one cycle"});
      ++report.refused;
      report.refusals.push_back("object " + std::to_string(pick.object_id) +
                                " not sent: more than max_poses " +
                                std::to_string(options_.max_poses) + " in one cycle");
      Log(report.refusals.back());
    }
  }
  report.admitted = static_cast<int>(admitted.size());
  if (cycle.status == 0 && admitted.empty() && !cycle.picks.empty()) {
    cycle.status = kErrorAllRefused;
    cycle.error = "the safety gate refused every pose of this cycle";
  }
  cycle.picks = std::move(admitted);
  Send(cycle);
  return report;
}

std::unique_ptr<RobotLink> OpenLink(const std::string& uri, SafetyGate gate, LinkOptions options) {
  const LinkUri parsed = ParseLinkUri(uri);
  if (parsed.scheme == "dryrun") return MakeDryRunLink(parsed, std::move(gate), std::move(options));
  if (parsed.scheme == "modbus-server") {
    return MakeModbusServerLink(parsed, std::move(gate), std::move(options));
  }
  if (parsed.scheme == "modbus-client") {
    return MakeModbusClientLink(parsed, std::move(gate), std::move(options));
  }
  if (parsed.scheme == "vision-server") {
    return MakeVisionServerLink(parsed, std::move(gate), std::move(options));
  }
  return MakeSerialLink(parsed, std::move(gate), std::move(options));
}

}  // namespace hnnstereo::robot
