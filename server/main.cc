// reconduit-server: the HTTP front of the reconstruction service (DESIGN.md sections 1 and 3).
//
// Parses the configuration (flags, then RECONDUIT_* environment variables), prepares the data
// folder (opens <data>/reconduit.db, removes orphaned uploads, sweeps expired leases), builds
// the route table (API routes from server/api, the web/ page as the fallback) and runs the HTTP
// server until SIGINT or SIGTERM. Exit status: 0 after a graceful shutdown, 1 when the server
// cannot start (port taken, data folder not writable, database unusable), 2 for bad flags.
#include "core/util/logging.h"
#include "server/api/api.h"
#include "server/api/maintenance.h"
#include "server/http/router.h"
#include "server/http/server.h"
#include "server/http/static_files.h"

#include <boost/program_options.hpp>

#include <cctype>
#include <chrono>
#include <cstdint>
#include <filesystem>
#include <iostream>
#include <memory>
#include <optional>
#include <string>

#ifndef RECONDUIT_DEFAULT_WEB_DIR
#define RECONDUIT_DEFAULT_WEB_DIR "web"
#endif
#ifndef RECONDUIT_VERSION
#define RECONDUIT_VERSION "dev"
#endif

namespace {

namespace fs = std::filesystem;
namespace po = boost::program_options;
using reconduit::server::HttpServerOptions;

struct Config {
  HttpServerOptions http;
  reconduit::server::UploadLimits limits;
  fs::path data_dir = "data";
  fs::path web_dir = RECONDUIT_DEFAULT_WEB_DIR;
  std::chrono::seconds lease_sweep_interval{30};
};

// "max-upload-bytes" <-> RECONDUIT_MAX_UPLOAD_BYTES.
std::string EnvironmentName(const std::string& option) {
  std::string name = "RECONDUIT_";
  for (const char c : option) {
    name += c == '-' ? '_' : static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  }
  return name;
}

// Returns the exit status to use when the program should stop now (help, bad flags).
std::optional<int> ParseConfig(int argc, char** argv, Config* config) {
  HttpServerOptions& http = config->http;
  std::string data_dir = config->data_dir.string();
  std::string web_dir = config->web_dir.string();
  std::int64_t header_timeout_s = 30;
  std::int64_t body_timeout_s = 30;
  std::int64_t write_timeout_s = 30;
  std::int64_t shutdown_grace_s = 10;
  std::int64_t lease_sweep_s = config->lease_sweep_interval.count();
  reconduit::server::UploadLimits& limits = config->limits;

  po::options_description options(
      "Usage: reconduit-server [options]\n\n"
      "Serves the Reconduit HTTP API and web page. Every option can also be set with an\n"
      "environment variable RECONDUIT_<OPTION> (upper case, '-' as '_'), e.g. "
      "RECONDUIT_PORT=9000;\n"
      "a flag on the command line wins over the environment.\n\nOptions");
  // clang-format off
  options.add_options()
      ("help,h", "Print this help and exit.")
      ("host", po::value(&http.host)->default_value(http.host),
       "Address to listen on (0.0.0.0 for every IPv4 interface).")
      ("port", po::value(&http.port)->default_value(http.port),
       "TCP port; 0 picks a free port (printed at start-up).")
      ("data", po::value(&data_dir)->default_value(data_dir),
       "Data folder (jobs, database); created if missing.")
      ("web", po::value(&web_dir)->default_value(web_dir),
       "Folder with the web page served at GET /.")
      ("threads", po::value(&http.num_threads)->default_value(http.num_threads),
       "I/O threads, 1-64.")
      ("token", po::value(&http.bearer_token),
       "Require 'Authorization: Bearer <token>' on every route but /healthz. Prefer the\n"
       "environment variable RECONDUIT_TOKEN: flags are visible to other local users.")
      ("max-upload-bytes", po::value(&http.max_upload_bytes)->default_value(http.max_upload_bytes),
       "Largest request body accepted by upload routes, in bytes.")
      ("max-body-bytes", po::value(&http.max_body_bytes)->default_value(http.max_body_bytes),
       "Largest body accepted by other routes (JSON requests), in bytes.")
      ("max-header-bytes", po::value(&http.max_header_bytes)->default_value(http.max_header_bytes),
       "Largest request line plus headers, in bytes.")
      ("max-connections", po::value(&http.max_connections)->default_value(http.max_connections),
       "Concurrent connections; more are answered 503 with Retry-After.")
      ("header-timeout", po::value(&header_timeout_s)->default_value(header_timeout_s),
       "Seconds allowed for a request header (also the keep-alive idle time).")
      ("body-timeout", po::value(&body_timeout_s)->default_value(body_timeout_s),
       "Seconds a request body may stall before the connection is dropped.")
      ("write-timeout", po::value(&write_timeout_s)->default_value(write_timeout_s),
       "Seconds a client may stall reading a response.")
      ("shutdown-grace", po::value(&shutdown_grace_s)->default_value(shutdown_grace_s),
       "Seconds in-flight requests may run after SIGINT/SIGTERM.")
      ("retry-after", po::value(&http.retry_after_seconds)->default_value(http.retry_after_seconds),
       "Seconds sent in Retry-After when the server is full.")
      ("max-photos", po::value(&limits.max_photos)->default_value(limits.max_photos),
       "Photos per job (image parts or zip entries); more are answered 413.")
      ("max-pixels", po::value(&limits.max_pixels)->default_value(limits.max_pixels),
       "Largest width*height of a photo, read from its header before decoding; larger\n"
       "photos are rejected (listed with the reason).")
      ("max-photo-bytes", po::value(&limits.max_photo_bytes)->default_value(limits.max_photo_bytes),
       "Largest single photo in bytes; larger ones are answered 413.")
      ("max-concurrent-uploads",
       po::value(&limits.max_concurrent_uploads)->default_value(limits.max_concurrent_uploads),
       "Uploads received at once; more are answered 429 with Retry-After.")
      ("max-queued-jobs", po::value(&limits.max_queued_jobs)->default_value(limits.max_queued_jobs),
       "Jobs waiting for a worker; new uploads are answered 503 with Retry-After when full.")
      ("lease-sweep-interval", po::value(&lease_sweep_s)->default_value(lease_sweep_s),
       "Seconds between sweeps that requeue jobs of workers that stopped heart-beating.");
  // clang-format on

  po::variables_map values;
  try {
    po::store(po::parse_command_line(argc, argv, options), values);
    // Stored second, so a value already given on the command line is kept.
    po::store(po::parse_environment(options,
                                    [&options](const std::string& variable) -> std::string {
                                      for (const auto& option : options.options()) {
                                        const std::string& name = option->long_name();
                                        if (name != "help" && EnvironmentName(name) == variable) {
                                          return name;
                                        }
                                      }
                                      return "";
                                    }),
              values);
    if (values.count("help") != 0) {
      std::cout << options << "\n";
      return 0;
    }
    po::notify(values);
  } catch (const po::error& e) {
    std::cerr << "reconduit-server: " << e.what() << "\nTry --help.\n";
    return 2;
  }

  http.header_timeout = std::chrono::seconds(header_timeout_s);
  http.body_timeout = std::chrono::seconds(body_timeout_s);
  http.write_timeout = std::chrono::seconds(write_timeout_s);
  http.shutdown_grace = std::chrono::seconds(shutdown_grace_s);
  http.server_name = std::string("reconduit/") + RECONDUIT_VERSION;
  config->data_dir = data_dir;
  config->web_dir = web_dir;
  config->lease_sweep_interval = std::chrono::seconds(lease_sweep_s);
  limits.max_upload_bytes = http.max_upload_bytes;

  std::string error;
  if (!http.Check(&error)) {
    std::cerr << "reconduit-server: invalid configuration: " << error << "\n";
    return 2;
  }
  const char* bad_limit = limits.max_photos < 1        ? "max-photos must be >= 1"
                          : limits.max_pixels < 1      ? "max-pixels must be >= 1"
                          : limits.max_photo_bytes < 1 ? "max-photo-bytes must be >= 1"
                          : limits.max_concurrent_uploads < 1
                              ? "max-concurrent-uploads must be >= 1"
                          : limits.max_queued_jobs < 1 ? "max-queued-jobs must be >= 1"
                          : lease_sweep_s < 1          ? "lease-sweep-interval must be >= 1"
                                                       : nullptr;
  if (bad_limit != nullptr) {
    std::cerr << "reconduit-server: invalid configuration: " << bad_limit << "\n";
    return 2;
  }
  return std::nullopt;
}

}  // namespace

int main(int argc, char** argv) {
  using namespace reconduit::server;  // NOLINT(build/namespaces)

  Config config;
  if (std::optional<int> exit_status = ParseConfig(argc, argv, &config)) return *exit_status;

  std::error_code ec;
  fs::create_directories(config.data_dir, ec);
  if (ec || !fs::is_directory(config.data_dir)) {
    std::cerr << "reconduit-server: cannot create data folder " << config.data_dir << ": "
              << (ec ? ec.message() : "not a directory") << "\n";
    return 1;
  }
  if (!fs::is_directory(config.web_dir)) {
    LOG_WARNING << "web folder " << config.web_dir
                << " does not exist: GET / will answer 404 (set --web or RECONDUIT_WEB)";
  } else if (!fs::is_regular_file(config.web_dir / "index.html")) {
    LOG_WARNING << "web folder " << config.web_dir << " has no index.html: GET / will answer 404";
  }

  // The job store and the data folder: orphans of a crash go before anything is served.
  const reconduit::DataLayout layout(fs::absolute(config.data_dir));
  reconduit::Result<std::unique_ptr<reconduit::JobStore>> store =
      reconduit::OpenSqliteJobStore(layout.DatabasePath().string());
  if (!store.ok()) {
    std::cerr << "reconduit-server: cannot open the job database " << layout.DatabasePath() << ": "
              << store.status().message() << "\n";
    return 1;
  }
  reconduit::Result<StartupReport> startup = PrepareDataFolder(layout, store->get());
  if (!startup.ok()) {
    std::cerr << "reconduit-server: cannot prepare the data folder " << layout.root() << ": "
              << startup.status().message() << "\n";
    return 1;
  }
  LOG_INFO << "start-up: removed " << startup->removed_temp_entries << " orphaned upload(s) and "
           << startup->removed_orphan_jobs << " orphaned job folder(s)";
  LeaseSweeper sweeper(store->get(), config.lease_sweep_interval);

  ApiServices services;
  services.data_dir = layout.root();
  services.retry_after_seconds = config.http.retry_after_seconds;
  services.store = store->get();
  services.limits = config.limits;
  services.http_metrics = std::make_shared<HttpMetrics>();
  config.http.metrics = services.http_metrics;

  Router router;
  AddApiRoutes(&router, &services);
  router.SetFallback(MakeStaticFileHandler(config.web_dir));

  HttpServer server(config.http, std::move(router));
  if (reconduit::Status status = server.Listen(); !status.ok()) {
    std::cerr << "reconduit-server: " << status.message() << "\n";
    return 1;
  }
  const std::string& host = config.http.host;
  const bool ipv6 = host.find(':') != std::string::npos;
  std::cout << "reconduit-server listening on http://" << (ipv6 ? "[" : "") << host
            << (ipv6 ? "]" : "") << ":" << server.port() << std::endl;
  LOG_INFO << "data folder " << services.data_dir << ", web folder " << config.web_dir << ", "
           << config.http.num_threads << " threads"
           << (config.http.bearer_token.empty() ? "" : ", bearer token required");

  if (reconduit::Status status = server.Run(); !status.ok()) {
    std::cerr << "reconduit-server: " << status.message() << "\n";
    return 1;
  }
  return 0;
}
