#include "web/cell_page_server.h"

#include <httplib.h>
#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <algorithm>
#include <atomic>
#include <charconv>
#include <chrono>
#include <condition_variable>
#include <deque>
#include <functional>
#include <list>
#include <mutex>
#include <stdexcept>
#include <thread>
#include <vector>

namespace hnnstereo::web {
namespace {

// The page's threads yield to the cell loop: nice 19 gives them about 1.5 % of a core that the
// loop wants (CFS weight 15 against 1024), all of one that it leaves idle. Linux applies
// setpriority(PRIO_PROCESS, tid) to the one thread.
void LowerThisThreadsPriority() {
  setpriority(PRIO_PROCESS, static_cast<id_t>(::syscall(SYS_gettid)), 19);
}

// httplib's ThreadPool, with workers at the lowest priority, made elastic: `base` workers stay;
// when a connection arrives and no worker is idle, another is started (up to `most`), and such
// extra workers end after kExtraIdle without work. A silent or byte-at-a-time client holds its
// worker until the read timeout; with a fixed pool 200 of them queued every later request behind
// 200 x the timeout (hand-written: httplib 0.11 has no elastic pool and no accept hook).
class LowPriorityThreadPool final : public httplib::TaskQueue {
 public:
  LowPriorityThreadPool(int base, int most) : base_(base), most_(std::max(base, most)) {
    std::lock_guard lock(mutex_);
    for (int i = 0; i < base_; ++i) StartWorkerLocked();
  }
  ~LowPriorityThreadPool() override { shutdown(); }

  void enqueue(std::function<void()> task) override {
    {
      std::lock_guard lock(mutex_);
      tasks_.push_back(std::move(task));
      if (idle_ < static_cast<int>(tasks_.size()) && running_ < most_ && !stopping_) {
        StartWorkerLocked();
      }
    }
    changed_.notify_one();
  }

  void shutdown() override {
    {
      std::lock_guard lock(mutex_);
      if (stopping_) return;
      stopping_ = true;
    }
    changed_.notify_all();
    std::unique_lock lock(mutex_);
    ended_.wait(lock, [this] { return running_ == 0; });
    lock.unlock();
    for (std::thread& worker : workers_) {
      if (worker.joinable()) worker.join();
    }
  }

 private:
  static constexpr std::chrono::seconds kExtraIdle{5};

  void StartWorkerLocked() {
    // Join the extra workers that ended since (they have left Work(); join waits at most for
    // their last instructions), so that months of bursts leave no unjoined threads behind.
    for (std::list<std::thread>::iterator ended : finished_) {
      ended->join();
      workers_.erase(ended);
    }
    finished_.clear();
    ++running_;
    workers_.emplace_back();
    const std::list<std::thread>::iterator self = std::prev(workers_.end());
    *self = std::thread([this, self] { Work(self); });
  }

  void Work(std::list<std::thread>::iterator self) {
    LowerThisThreadsPriority();
    std::unique_lock lock(mutex_);
    for (;;) {
      ++idle_;
      const bool woken = changed_.wait_for(lock, kExtraIdle,
                                           [this] { return stopping_ || !tasks_.empty(); });
      --idle_;
      if ((stopping_ && tasks_.empty()) || (!woken && running_ > base_)) break;
      if (tasks_.empty()) continue;
      std::function<void()> task = std::move(tasks_.front());
      tasks_.pop_front();
      lock.unlock();
      task();
      lock.lock();
    }
    if (!stopping_) finished_.push_back(self);  // joined by the next StartWorkerLocked
    --running_;
    ended_.notify_all();
  }

  const int base_;
  const int most_;
  std::mutex mutex_;
  std::condition_variable changed_;
  std::condition_variable ended_;
  std::deque<std::function<void()>> tasks_;
  std::list<std::thread> workers_;
  std::vector<std::list<std::thread>::iterator> finished_;
  int running_ = 0;
  int idle_ = 0;
  bool stopping_ = false;
};

std::string StripBrackets(const std::string& host) {
  if (host.size() >= 2 && host.front() == '[' && host.back() == ']') {
    return host.substr(1, host.size() - 2);
  }
  return host;
}

// Compares without stopping at the first difference (the time does not tell how much matched).
bool SameToken(const std::string& given, const std::string& expected) {
  unsigned char difference = given.size() == expected.size() ? 0 : 1;
  for (std::size_t i = 0; i < given.size(); ++i) {
    difference |= static_cast<unsigned char>(given[i] ^ expected[i % expected.size()]);
  }
  return difference == 0;
}

bool Authorized(const httplib::Request& request, const std::string& token) {
  if (token.empty()) return true;
  const std::string header = request.get_header_value("Authorization");
  const std::string bearer = "Bearer ";
  if (header.rfind(bearer, 0) == 0 && SameToken(header.substr(bearer.size()), token)) return true;
  return request.has_param("token") && SameToken(request.get_param_value("token"), token);
}

const char* ReasonOf(int status) {
  switch (status) {
    case 401:
      return "401 unauthorized: this page needs its token (?token=T or "
             "'Authorization: Bearer T')";
    case 404:
      return "404 not found: the page is /, the API /api/status, /api/objects, "
             "/api/cycles, /api/left.png, /api/overlay.png";
    case 405:
      return "405 method not allowed: the page is read-only (GET, HEAD)";
    case 503:
      return "503 nothing published yet: the cell loop has not started";
    default:
      return "error";
  }
}

}  // namespace

bool IsLoopbackHost(const std::string& host_text) {
  const std::string host = StripBrackets(host_text);
  if (host == "localhost") return true;
  in_addr v4{};
  if (inet_pton(AF_INET, host.c_str(), &v4) == 1) return (ntohl(v4.s_addr) >> 24) == 127;
  in6_addr v6{};
  if (inet_pton(AF_INET6, host.c_str(), &v6) == 1) return IN6_IS_ADDR_LOOPBACK(&v6);
  return false;
}

std::string CellPageOptions::Check() const {
  if (host.empty()) return "--http: the host is empty (127.0.0.1:PORT for this machine only)";
  if (port < 0 || port > 65535) return "--http: port " + std::to_string(port) + " not in 0..65535";
  if (threads < 1) return "http threads must be >= 1";
  if (max_threads < threads || max_threads > 1024) return "http max threads must be in [threads, 1024]";
  if (read_timeout_s < 1 || read_timeout_s > 60) return "http read timeout must be 1-60 s";
  if (write_timeout_s < 1) return "http write timeout must be >= 1 s";
  if (!(max_images_per_second >= 0.0)) return "max_images_per_second must be >= 0";
  if (!IsLoopbackHost(host) && token.empty()) {
    return "--http " + host + ":" + std::to_string(port) +
           " is reachable from other machines: give --http-token T (requests without it get "
           "401), or bind 127.0.0.1";
  }
  return {};
}

CellPageOptions ParseHttpAddress(const std::string& address) {
  const auto colon = address.rfind(':');
  if (colon == std::string::npos || colon + 1 == address.size()) {
    throw std::invalid_argument("--http '" + address +
                                "': expected HOST:PORT (127.0.0.1:8080; port 0 = any free port)");
  }
  CellPageOptions options;
  const std::string host = address.substr(0, colon);
  if (!host.empty()) options.host = host;
  const std::string port_text = address.substr(colon + 1);
  int port = -1;
  const auto [end, error] =
      std::from_chars(port_text.data(), port_text.data() + port_text.size(), port);
  if (error != std::errc() || end != port_text.data() + port_text.size() || port < 0 ||
      port > 65535) {
    throw std::invalid_argument("--http '" + address + "': port '" + port_text +
                                "' is not a number in 0..65535");
  }
  options.port = port;
  return options;
}

struct CellPageServer::Impl {
  const CellStatusBoard& board;
  CellPageOptions options;
  httplib::Server server;
  int port = 0;
  int listening_socket = -1;  ///< the last socket httplib made for binding
  std::mutex image_pace_mutex;
  std::chrono::steady_clock::time_point next_image_slot{};

  // Waits for this answer's turn under max_images_per_second (on the HTTP thread, never the
  // loop's).
  void PaceImages() {
    if (!(options.max_images_per_second > 0.0)) return;
    const auto interval = std::chrono::duration_cast<std::chrono::steady_clock::duration>(
        std::chrono::duration<double>(1.0 / options.max_images_per_second));
    std::chrono::steady_clock::time_point slot;
    {
      std::lock_guard lock(image_pace_mutex);
      slot = std::max(std::chrono::steady_clock::now(), next_image_slot);
      next_image_slot = slot + interval;
    }
    std::this_thread::sleep_until(slot);
  }
  std::thread thread;
  std::atomic<bool> listener_done{false};

  Impl(const CellStatusBoard& b, CellPageOptions o) : board(b), options(std::move(o)) {}

  // The latest snapshot, or a 503 answer when the loop has published none yet.
  std::shared_ptr<const CellSnapshot> Latest(httplib::Response& response) const {
    auto snapshot = board.Latest();
    if (!snapshot) response.status = 503;
    return snapshot;
  }

  void Routes() {
    const int threads = options.threads;
    const int most = options.max_threads;
    server.new_task_queue = [threads, most] { return new LowPriorityThreadPool(threads, most); };
    server.set_write_timeout(options.write_timeout_s, 0);
    server.set_read_timeout(options.read_timeout_s, 0);
    server.set_keep_alive_max_count(20);
    server.set_keep_alive_timeout(2);
    server.set_payload_max_length(64 * 1024);
    server.set_socket_options([this](socket_t socket) {
      const int yes = 1;  // httplib's default options, which this callback replaces
      setsockopt(socket, SOL_SOCKET, SO_REUSEADDR, &yes, sizeof yes);
#ifdef TCP_DEFER_ACCEPT
      // A connection reaches httplib (and takes one of its worker threads) only once it has
      // sent data: clients that connect and stay silent no longer queue up in front of
      // everyone else (Linux, tcp(7)).
      const int defer_s = 5;
      setsockopt(socket, IPPROTO_TCP, TCP_DEFER_ACCEPT, &defer_s, sizeof defer_s);
#endif
      listening_socket = socket;
    });
    server.set_default_headers(
        {{"Cache-Control", "no-store"}, {"X-Content-Type-Options", "nosniff"}});
    server.set_pre_routing_handler(
        [this](const httplib::Request& request, httplib::Response& response) {
          if (!Authorized(request, options.token)) {
            response.status = 401;
            response.set_header("WWW-Authenticate", "Bearer");
            response.set_content(ReasonOf(401) + std::string("\n"), "text/plain");
            return httplib::Server::HandlerResponse::Handled;
          }
          if (request.method != "GET" && request.method != "HEAD") {
            response.status = 405;
            response.set_header("Allow", "GET, HEAD");
            response.set_content(ReasonOf(405) + std::string("\n"), "text/plain");
            return httplib::Server::HandlerResponse::Handled;
          }
          return httplib::Server::HandlerResponse::Unhandled;
        });
    server.set_error_handler([](const httplib::Request&, httplib::Response& response) {
      if (response.body.empty()) {
        response.set_content(ReasonOf(response.status) + std::string("\n"), "text/plain");
      }
    });
    server.Get("/", [](const httplib::Request&, httplib::Response& response) {
      response.set_content(CellPageHtml(), "text/html; charset=utf-8");
    });
    auto json_route = [this](const char* path, const std::string& (CellSnapshot::*text)() const) {
      server.Get(path, [this, text](const httplib::Request&, httplib::Response& response) {
        if (auto snapshot = Latest(response)) {
          response.set_content(((*snapshot).*text)(), "application/json");
        }
      });
    };
    json_route("/api/status", &CellSnapshot::StatusText);
    json_route("/api/cycles", &CellSnapshot::CyclesText);
    server.Get("/api/objects", [this](const httplib::Request&, httplib::Response& response) {
      if (auto snapshot = Latest(response)) {
        if (snapshot->state.objects.is_null()) {
          response.status = 404;
          response.set_content("404 no objects sensed yet\n", "text/plain");
        } else {
          response.set_content(snapshot->ObjectsText(), "application/json");
        }
      }
    });
    auto png_route = [this](const char* path, const std::string& (CellSnapshot::*png)() const) {
      server.Get(path, [this, png](const httplib::Request&, httplib::Response& response) {
        PaceImages();
        if (auto snapshot = Latest(response)) {
          const std::string& bytes = ((*snapshot).*png)();
          if (bytes.empty()) {
            response.status = 404;
            response.set_content("404 no image yet (replayed objects have none)\n", "text/plain");
          } else {
            // The snapshot is held by the lambda until the body is sent; no copy of the PNG.
            response.set_content_provider(bytes.size(), "image/png",
                                          [snapshot, &bytes](std::size_t offset, std::size_t length,
                                                             httplib::DataSink& sink) {
                                            return sink.write(bytes.data() + offset, length);
                                          });
          }
        }
      });
    };
    png_route("/api/left.png", &CellSnapshot::LeftPng);
    png_route("/api/overlay.png", &CellSnapshot::OverlayPng);
  }
};

CellPageServer::CellPageServer(const CellStatusBoard& board, CellPageOptions options)
    : impl_(std::make_unique<Impl>(board, std::move(options))) {
  if (auto error = impl_->options.Check(); !error.empty()) throw std::invalid_argument(error);
  impl_->Routes();
  const std::string host = StripBrackets(impl_->options.host);
  if (impl_->options.port == 0) {
    impl_->port = impl_->server.bind_to_any_port(host);
  } else if (impl_->server.bind_to_port(host, impl_->options.port)) {
    impl_->port = impl_->options.port;
  } else {
    impl_->port = -1;
  }
  // Debian's libcpp-httplib 0.11 listens with a backlog of 5: 50 clients connecting at once would
  // see their connections dropped. A second listen() on Linux only raises the backlog.
  if (impl_->port > 0 && impl_->listening_socket >= 0) ::listen(impl_->listening_socket, 256);
  if (impl_->port <= 0) {
    throw std::runtime_error("--http: cannot listen on " + impl_->options.host + ":" +
                             std::to_string(impl_->options.port) +
                             " (address in use or not of this machine)");
  }
  impl_->thread = std::thread([this] {
    LowerThisThreadsPriority();
    impl_->server.listen_after_bind();
    impl_->listener_done = true;
  });
}

CellPageServer::~CellPageServer() {
  // stop() only ends a listener that is running: wait for it to have started.
  while (!impl_->server.is_running() && !impl_->listener_done) {
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  impl_->server.stop();
  if (impl_->thread.joinable()) impl_->thread.join();
}

int CellPageServer::port() const { return impl_->port; }

std::string CellPageServer::Url() const {
  const std::string& host = impl_->options.host;
  const bool v6 = host.find(':') != std::string::npos && host.front() != '[';
  return "http://" + (v6 ? "[" + host + "]" : host) + ":" + std::to_string(impl_->port) + "/";
}

}  // namespace hnnstereo::web
