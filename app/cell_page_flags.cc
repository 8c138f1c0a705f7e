#include "app/cell_page_flags.h"

#include <cstdio>
#include <stdexcept>

namespace hnnstereo::app {

void CellPageFlags::AddTo(CLI::App* cmd, const std::string& http_help) {
  cmd->add_option("--http", http, http_help);
  cmd->add_option("--http-token", token,
                  "Every request to the page must carry this token (open the page as "
                  "http://HOST:PORT/?token=T, or send 'Authorization: Bearer T'); required when "
                  "--http binds an address other than loopback");
}

std::optional<web::CellPageOptions> CellPageFlags::Resolve() const {
  if (http.empty()) {
    if (!token.empty()) throw std::invalid_argument("--http-token is used with --http HOST:PORT");
    return std::nullopt;
  }
  web::CellPageOptions options = web::ParseHttpAddress(http);
  options.token = token;
  if (auto error = options.Check(); !error.empty()) throw std::invalid_argument(error);
  return options;
}

std::unique_ptr<web::CellPageServer> StartCellPage(const web::CellStatusBoard& board,
                                                   const web::CellPageOptions& options) {
  auto server = std::make_unique<web::CellPageServer>(board, options);
  std::printf("http: %s%s\n", server->Url().c_str(),
              options.token.empty() ? "" : " (token required: ?token=T)");
  std::fflush(stdout);
  return server;
}

}  // namespace hnnstereo::app
