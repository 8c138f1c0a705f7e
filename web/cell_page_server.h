#pragma once
// The cell's web page and its JSON/PNG API over HTTP (cpp-httplib, Debian's libcpp-httplib-dev):
//   /                  one self-contained page (inline CSS and JS, no external assets)
//   /api/status        JSON: parts with their picks, link, counters, last cycle, last error
//   /api/objects       OBJECTS.json exactly
//   /api/cycles        JSON: the last 100 cycles' times
//   /api/left.png      the latest left image
//   /api/overlay.png   the same with the parts' outlines, ids, centres and yaw lines
// Read-only: GET and HEAD only, nothing here reaches the robot link. The server only reads the
// snapshots the cell loop publishes to a CellStatusBoard; its threads run at the lowest CPU
// priority, so many or slow clients take what the loop leaves over.

#include <memory>
#include <string>

#include "web/cell_status.h"

namespace hnnstereo::web {

struct CellPageOptions {
  std::string host = "127.0.0.1";  ///< address to bind; any non-loopback one needs a token
  int port = 0;                    ///< 0 = any free port (CellPageServer::port() names it)
  /// When set, every request must carry it (`Authorization: Bearer T` or `?token=T`), else 401.
  std::string token;
  int threads = 8;          ///< HTTP worker threads kept (each serves one connection at a time)
  /// Workers added while every worker is busy, up to this many in all (idle extra ones end after
  /// a few seconds): connections that send nothing hold a worker each for `read_timeout_s`, so a
  /// crowd of them after the accept deferral must not leave a real request waiting in a queue.
  int max_threads = 128;
  /// A client that sends nothing for this long (between the bytes of a request, or after a
  /// keep-alive answer) is dropped. A browser on the cell's network sends a request at once.
  int read_timeout_s = 1;
  int write_timeout_s = 5;  ///< a client that stops reading is dropped after this long
  /// At most this many PNG answers a second over all clients (the rest wait their turn): bounds
  /// the page's total work - encoding, copying, the kernel's sends - however many clients poll
  /// as fast as they can. The image changes once a cycle, so 10 viewers refreshing every second
  /// fit; web_cell_page_load_test holds the cell loop within 1.10x of its cycle time alone with
  /// 50 clients polling (docs/robot.md). 0 = no limit.
  double max_images_per_second = 10.0;
  /// Empty when usable; otherwise a one-line reason (bad port, non-loopback host without token).
  std::string Check() const;
};

/// Parses `HOST:PORT` (`127.0.0.1:8080`, `0.0.0.0:0`, `[::1]:8080`, `localhost:0`) into options;
/// throws std::invalid_argument naming the text.
CellPageOptions ParseHttpAddress(const std::string& address);

/// True for 127.0.0.0/8, ::1 and "localhost".
bool IsLoopbackHost(const std::string& host);

class CellPageServer {
 public:
  /// Binds and starts serving on a background thread. Throws std::invalid_argument when
  /// options.Check() fails, std::runtime_error when the address cannot be bound.
  CellPageServer(const CellStatusBoard& board, CellPageOptions options);
  ~CellPageServer();  ///< stops and joins
  CellPageServer(const CellPageServer&) = delete;
  CellPageServer& operator=(const CellPageServer&) = delete;

  int port() const;
  /// http://HOST:PORT/ as bound.
  std::string Url() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// The page served at `/` (web/cell_page.html, embedded at build time).
const std::string& CellPageHtml();

}  // namespace hnnstereo::web
