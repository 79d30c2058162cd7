// reconduit-server: the HTTP front of the reconstruction service (DESIGN.md sections 1 and 3).
//
// Parses the configuration (flags, then RECONDUIT_* environment variables, then the --config
// file's top-level names and [server] section; see config/config.h), prepares the data folder
// (opens <data>/reconduit.db, removes orphaned uploads, sweeps expired leases), builds the route
// table (API routes from server/api, the web/ page as the fallback) and runs the HTTP server until
// SIGINT or SIGTERM. Exit status: 0 after a graceful shutdown, 1 when the server cannot start (port
// taken, data folder not writable, database unusable), 2 for bad flags or a bad configuration file.
#include "core/util/logging.h"
#include "server/api/api.h"
#include "server/api/maintenance.h"
#include "server/http/router.h"
#include "server/http/server.h"
#include "server/http/static_files.h"

#include "config/config.h"
#include <chrono>
#include <csignal>
#include <cstdint>
#include <filesystem>
#include <iostream>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

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

// The settings as given; FinishConfig derives the rest.
struct Config {
  HttpServerOptions http;
  reconduit::server::UploadLimits limits;
  std::string data_dir = "data";
  std::string web_dir = RECONDUIT_DEFAULT_WEB_DIR;
  std::int64_t header_timeout_s = 30;
  std::int64_t body_timeout_s = 30;
  std::int64_t write_timeout_s = 30;
  std::int64_t shutdown_grace_s = 10;
  std::int64_t lease_sweep_s = 30;
};

constexpr char kUsage[] =
    "Usage: reconduit-server [options]\n\n"
    "Serves the Reconduit HTTP API and web page. Every option can also be set with an\n"
    "environment variable RECONDUIT_<OPTION> (upper case, '-' as '_'), e.g. RECONDUIT_PORT=9000,\n"
    "or in the configuration file given by --config: 'option = value' lines at the top or\n"
    "under [server] (same names as the flags without '--'). A flag on the command line wins\n"
    "over the environment, which wins over the config file, which wins over the defaults.\n";

constexpr char kEpilogue[] =
    "Exit status: 0 after a graceful shutdown (SIGINT, SIGTERM), 1 when the server cannot\n"
    "start, 2 for bad flags, environment or config file.\n";

// The option table, bound to the fields of *config.
reconduit::config::ProgramSettings ServerProgram(Config* config) {
  reconduit::config::ProgramSettings program;
  program.program = "reconduit-server";
  program.section = "server";
  program.usage = kUsage;
  program.epilogue = kEpilogue;
  HttpServerOptions& http = config->http;
  reconduit::server::UploadLimits& limits = config->limits;
  // clang-format off
  program.options.add_options()
      ("host", po::value(&http.host)->value_name("ADDRESS")->default_value(http.host),
       "Address to listen on (0.0.0.0 for every IPv4 interface).")
      ("port", po::value(&http.port)->value_name("PORT")->default_value(http.port),
       "TCP port; 0 picks a free port (printed at start-up).")
      ("data", po::value(&config->data_dir)->value_name("DIR")->default_value(config->data_dir),
       "Data folder (jobs, database) shared with reconduit-worker; created if missing.")
      ("web", po::value(&config->web_dir)->value_name("DIR")->default_value(config->web_dir),
       "Folder with the web page served at GET /.")
      ("threads", po::value(&http.num_threads)->value_name("N")->default_value(http.num_threads),
       "I/O threads, 1-64.")
      ("token", po::value(&http.bearer_token)->value_name("TOKEN"),
       "Require 'Authorization: Bearer <token>' on every route but /healthz. Prefer the "
       "environment variable RECONDUIT_TOKEN: flags are visible to other local users.")
      ("max-upload-bytes", po::value(&http.max_upload_bytes)->value_name("BYTES")->default_value(http.max_upload_bytes),
       "Largest request body accepted by upload routes, in bytes.")
      ("max-body-bytes", po::value(&http.max_body_bytes)->value_name("BYTES")->default_value(http.max_body_bytes),
       "Largest body accepted by other routes (JSON requests), in bytes.")
      ("max-header-bytes", po::value(&http.max_header_bytes)->value_name("BYTES")->default_value(http.max_header_bytes),
       "Largest request line plus headers, in bytes.")
      ("max-connections", po::value(&http.max_connections)->value_name("N")->default_value(http.max_connections),
       "Concurrent connections; more are answered 503 with Retry-After.")
      ("max-connections-per-address",
       po::value(&http.max_connections_per_address)->value_name("N")->default_value(http.max_connections_per_address),
       "Concurrent connections from one client address (>= 1); more are answered "
       "503 with Retry-After (GET /healthz is still answered).")
      ("upload-threads", po::value(&http.blocking_threads)->value_name("N")->default_value(http.blocking_threads),
       "Threads that store and check uploads (disk writes, zip extraction, photo checks, fsync) "
       "off the I/O threads, 1-64.")
      ("header-timeout",
       po::value(&config->header_timeout_s)->value_name("SECONDS")->default_value(config->header_timeout_s),
       "Seconds allowed for a request header (also the keep-alive idle time).")
      ("body-timeout", po::value(&config->body_timeout_s)->value_name("SECONDS")->default_value(config->body_timeout_s),
       "Seconds a request body may stall before the connection is dropped.")
      ("write-timeout",
       po::value(&config->write_timeout_s)->value_name("SECONDS")->default_value(config->write_timeout_s),
       "Seconds a client may stall reading a response.")
      ("shutdown-grace",
       po::value(&config->shutdown_grace_s)->value_name("SECONDS")->default_value(config->shutdown_grace_s),
       "Seconds in-flight requests may run after SIGINT/SIGTERM.")
      ("retry-after", po::value(&http.retry_after_seconds)->value_name("SECONDS")->default_value(http.retry_after_seconds),
       "Seconds sent in Retry-After when the server is full.")
      ("max-photos", po::value(&limits.max_photos)->value_name("N")->default_value(limits.max_photos),
       "Photos per job (image parts or zip entries); more are answered 413.")
      ("max-pixels", po::value(&limits.max_pixels)->value_name("N")->default_value(limits.max_pixels),
       "Largest width*height of a photo, read from its header before decoding; larger "
       "photos are rejected (listed with the reason).")
      ("max-photo-bytes", po::value(&limits.max_photo_bytes)->value_name("BYTES")->default_value(limits.max_photo_bytes),
       "Largest single photo in bytes; larger ones are answered 413.")
      ("max-concurrent-uploads",
       po::value(&limits.max_concurrent_uploads)->value_name("N")->default_value(limits.max_concurrent_uploads),
       "Uploads received at once; more are answered 429 with Retry-After.")
      ("max-queued-jobs", po::value(&limits.max_queued_jobs)->value_name("N")->default_value(limits.max_queued_jobs),
       "Jobs waiting for a worker; new uploads are answered 503 with Retry-After when full.")
      ("lease-sweep-interval",
       po::value(&config->lease_sweep_s)->value_name("SECONDS")->default_value(config->lease_sweep_s),
       "Seconds between sweeps that requeue jobs of workers that stopped heart-beating.");
  // clang-format on
  program.environment = reconduit::config::DefaultEnvironment(program.options);
  return program;
}

// The option behind a field name in HttpServerOptions::Check's messages.
std::string OptionOfField(const std::string& message) {
  static const std::map<std::string, std::string> kFields = {
      {"host", "host"},
      {"port", "port"},
      {"num_threads", "threads"},
      {"max_connections", "max-connections"},
      {"max_connections_per_address", "max-connections-per-address"},
      {"blocking_threads", "upload-threads"},
      {"max_header_bytes", "max-header-bytes"},
      {"max_body_bytes", "max-body-bytes"},
      {"max_upload_bytes", "max-upload-bytes"},
      {"shutdown_grace", "shutdown-grace"},
      {"retry_after_seconds", "retry-after"},
      {"bearer_token", "token"}};
  const auto it = kFields.find(message.substr(0, message.find(' ')));
  return it == kFields.end() ? "" : it->second;
}

// Derives the HTTP options' durations and checks every range; false after printing the
// problem and where the value came from.
bool FinishConfig(const reconduit::config::Settings& settings, Config* config) {
  HttpServerOptions& http = config->http;
  http.header_timeout = std::chrono::seconds(config->header_timeout_s);
  http.body_timeout = std::chrono::seconds(config->body_timeout_s);
  http.write_timeout = std::chrono::seconds(config->write_timeout_s);
  http.shutdown_grace = std::chrono::seconds(config->shutdown_grace_s);
  http.server_name = std::string("reconduit/") + RECONDUIT_VERSION;
  config->limits.max_upload_bytes = http.max_upload_bytes;

  std::string error;
  if (!http.Check(&error)) {
    std::cerr << "reconduit-server: invalid configuration: " << error
              << settings.From(OptionOfField(error)) << "\n";
    return false;
  }
  const reconduit::server::UploadLimits& limits = config->limits;
  const std::pair<bool, const char*> limit_checks[] = {
      {limits.max_photos >= 1, "max-photos"},
      {limits.max_pixels >= 1, "max-pixels"},
      {limits.max_photo_bytes >= 1, "max-photo-bytes"},
      {limits.max_concurrent_uploads >= 1, "max-concurrent-uploads"},
      {limits.max_queued_jobs >= 1, "max-queued-jobs"},
      {config->lease_sweep_s >= 1, "lease-sweep-interval"}};
  for (const auto& [ok, option] : limit_checks) {
    if (!ok) {
      std::cerr << "reconduit-server: invalid configuration: " << option << " must be >= 1"
                << settings.From(option) << "\n";
      return false;
    }
  }
  return true;
}

// Flags, then RECONDUIT_* environment variables, then the config file, then the defaults.
// Returns the exit status to use when the program should stop now (help, bad settings).
std::optional<int> ParseConfig(int argc, char** argv, Config* config) {
  const reconduit::config::ProgramSettings program = ServerProgram(config);
  reconduit::config::Settings settings;
  if (std::optional<int> status =
          reconduit::config::ParseSettings(program, std::vector<std::string>(argv + 1, argv + argc),
                                           &settings, std::cout, std::cerr)) {
    return status;
  }
  if (!FinishConfig(settings, config)) return 2;
  return std::nullopt;
}

}  // namespace

int main(int argc, char** argv) {
  using namespace reconduit::server;  // NOLINT(build/namespaces)
  // A write over a file size limit (RLIMIT_FSIZE, set by an operator or a container) must fail
  // with EFBIG, answered like a full disk, not kill the server with SIGXFSZ.
  std::signal(SIGXFSZ, SIG_IGN);

  Config config;
  if (std::optional<int> exit_status = ParseConfig(argc, argv, &config)) return *exit_status;
  const fs::path data_dir = config.data_dir;
  const fs::path web_dir = config.web_dir;

  std::error_code ec;
  fs::create_directories(data_dir, ec);
  if (ec || !fs::is_directory(data_dir)) {
    std::cerr << "reconduit-server: cannot create data folder " << data_dir << ": "
              << (ec ? ec.message() : "not a directory") << "\n";
    return 1;
  }
  if (!fs::is_directory(web_dir)) {
    LOG_WARNING << "web folder " << web_dir
                << " does not exist: GET / will answer 404 (set --web or RECONDUIT_WEB)";
  } else if (!fs::is_regular_file(web_dir / "index.html")) {
    LOG_WARNING << "web folder " << web_dir << " has no index.html: GET / will answer 404";
  }

  // The job store and the data folder: orphans of a crash go before anything is served.
  const reconduit::DataLayout layout(fs::absolute(data_dir));
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
  LeaseSweeper sweeper(store->get(), std::chrono::seconds(config.lease_sweep_s));

  ApiServices services;
  services.data_dir = layout.root();
  services.retry_after_seconds = config.http.retry_after_seconds;
  services.store = store->get();
  services.limits = config.limits;
  services.http_metrics = std::make_shared<HttpMetrics>();
  config.http.metrics = services.http_metrics;

  Router router;
  AddApiRoutes(&router, &services);
  router.SetFallback(MakeStaticFileHandler(web_dir));
  if (!config.http.bearer_token.empty()) {
    // The page's own files need no token (issue 12): a browser cannot send one with a
    // navigation or a script, style or module load, and they hold nothing but the page, which
    // then asks for the token and sends it with every API call. Every other path still
    // answers 401 without it, unknown ones included.
    const std::vector<std::string> page = StaticFilePaths(web_dir);
    config.http.public_paths.insert(config.http.public_paths.end(), page.begin(), page.end());
    LOG_INFO << "bearer token required except on /healthz and the " << page.size()
             << " file path(s) of the web page";
  }

  HttpServer server(config.http, std::move(router));
  if (reconduit::Status status = server.Listen(); !status.ok()) {
    std::cerr << "reconduit-server: " << status.message() << "\n";
    return 1;
  }
  const std::string& host = config.http.host;
  const bool ipv6 = host.find(':') != std::string::npos;
  std::cout << "reconduit-server listening on http://" << (ipv6 ? "[" : "") << host
            << (ipv6 ? "]" : "") << ":" << server.port() << std::endl;
  LOG_INFO << "data folder " << services.data_dir << ", web folder " << web_dir << ", "
           << config.http.num_threads << " threads"
           << (config.http.bearer_token.empty() ? "" : ", bearer token required");

  if (reconduit::Status status = server.Run(); !status.ok()) {
    std::cerr << "reconduit-server: " << status.message() << "\n";
    return 1;
  }
  return 0;
}
