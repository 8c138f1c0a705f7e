#pragma once
// The cell's web page on the command line, shared by `serve` and `view`: --http HOST:PORT and
// --http-token T, checked before anything starts, and the server started with its URL printed.

#include <CLI/CLI.hpp>
#include <memory>
#include <optional>
#include <string>

#include "web/cell_page_server.h"
#include "web/cell_status.h"

namespace hnnstereo::app {

struct CellPageFlags {
  std::string http;   ///< HOST:PORT; empty = no page
  std::string token;  ///< required for a non-loopback HOST
  void AddTo(CLI::App* cmd, const std::string& http_help);
  /// nullopt without --http. Throws std::invalid_argument with a one-line reason (malformed
  /// address, non-loopback address without --http-token, a token without --http).
  std::optional<web::CellPageOptions> Resolve() const;
};

/// Starts the page's server on `board` and prints `http: URL` (flushed, like the link's line).
std::unique_ptr<web::CellPageServer> StartCellPage(const web::CellStatusBoard& board,
                                                   const web::CellPageOptions& options);

}  // namespace hnnstereo::app
