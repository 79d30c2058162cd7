// reconduit-server: the HTTP front of the reconstruction service (DESIGN.md sections 1 and 3).
//
// Parses the configuration (flags, then RECONDUIT_* environment variables, then the --config
// file), prepares the data folder (opens <data>/reconduit.db, removes orphaned uploads, sweeps
// expired leases), builds the route table (API routes from server/api, the web/ page as the
// fallback) and runs the HTTP server until SIGINT or SIGTERM. Exit status: 0 after a graceful
// shutdown, 1 when the server cannot start (port taken, data folder not writable, database
// unusable), 2 for bad flags or a bad configuration file.
#include "core/util/logging.h"
#include "server/api/api.h"
#include "server/api/maintenance.h"
#include "server/http/router.h"
#include "server/http/server.h"
#include "server/http/static_files.h"

#include <boost/program_options.hpp>

#include <cctype>
#include <cerrno>
#include <chrono>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <utility>

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

// Where each option's value came from, for error messages: "--port", "RECONDUIT_PORT" or
// "'port' in FILE". Options left at their defaults are absent.
using Sources = std::map<std::string, std::string>;

void AddSources(const po::parsed_options& parsed,
                const std::string& prefix,
                const std::string& suffix,
                bool env_names,
                Sources* sources) {
  for (const po::option& option : parsed.options) {
    if (option.unregistered || option.string_key.empty()) continue;
    const std::string& key = option.string_key;
    sources->emplace(key, env_names ? EnvironmentName(key) : prefix + key + suffix);
  }
}

// " (from X)" for an option set on the command line, in the environment or in the file.
std::string SourceOf(const Sources& sources, const std::string& option) {
  const auto it = sources.find(option);
  return it == sources.end() ? "" : " (from " + it->second + ")";
}

// The option behind a field name in HttpServerOptions::Check's messages.
std::string OptionOfField(const std::string& message) {
  static const std::map<std::string, std::string> kFields = {
      {"host", "host"},
      {"port", "port"},
      {"num_threads", "threads"},
      {"max_connections", "max-connections"},
      {"max_header_bytes", "max-header-bytes"},
      {"max_body_bytes", "max-body-bytes"},
      {"max_upload_bytes", "max-upload-bytes"},
      {"shutdown_grace", "shutdown-grace"},
      {"retry_after_seconds", "retry-after"},
      {"bearer_token", "token"}};
  const auto it = kFields.find(message.substr(0, message.find(' ')));
  return it == kFields.end() ? "" : it->second;
}

// Returns the exit status to use when the program should stop now (help, bad flags, bad
// configuration file).
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
  std::string config_file;

  po::options_description general(
      "Usage: reconduit-server [options]\n\n"
      "Serves the Reconduit HTTP API and web page. Every option can also be set with an\n"
      "environment variable RECONDUIT_<OPTION> (upper case, '-' as '_'), e.g. "
      "RECONDUIT_PORT=9000,\n"
      "or as 'option = value' lines in the file given by --config (same names as the flags\n"
      "without '--'; '#' starts a comment). A flag on the command line wins over the\n"
      "environment, which wins over the config file, which wins over the defaults.\n\nOptions");
  // clang-format off
  general.add_options()
      ("help,h", "Print this help and exit.")
      ("config", po::value(&config_file),
       "Read options from this INI-style file of 'option = value' lines (env\n"
       "RECONDUIT_CONFIG). An unknown option or a bad value in it is an error.");
  po::options_description settings;
  settings.add_options()
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
  po::options_description options;
  options.add(general).add(settings);

  po::variables_map values;
  Sources sources;
  try {
    const po::parsed_options command_line = po::parse_command_line(argc, argv, options);
    po::store(command_line, values);
    if (values.count("help") != 0) {
      std::cout << options << "\n";
      return 0;
    }
    AddSources(command_line, "--", "", false, &sources);
  } catch (const po::error& e) {
    std::cerr << "reconduit-server: " << e.what() << "\nTry --help.\n";
    return 2;
  }
  try {
    // Stored second, so a value already given on the command line is kept.
    const po::parsed_options environment =
        po::parse_environment(options, [&options](const std::string& variable) -> std::string {
          for (const auto& option : options.options()) {
            const std::string& name = option->long_name();
            if (name != "help" && EnvironmentName(name) == variable) return name;
          }
          return "";
        });
    po::store(environment, values);
    AddSources(environment, "", "", true, &sources);
  } catch (const po::error& e) {
    std::cerr << "reconduit-server: in the environment (RECONDUIT_*): " << e.what() << "\n";
    return 2;
  }
  if (values.count("config") != 0) {
    // Stored last: the command line and the environment win over the file.
    const std::string path = values["config"].as<std::string>();
    std::ifstream file(path);
    if (!file) {
      std::cerr << "reconduit-server: cannot read the config file '" << path
                << "': " << std::strerror(errno) << "\n";
      return 2;
    }
    try {
      // Unknown keys (including "config" and "help") are errors: a typo must not pass
      // silently.
      const po::parsed_options parsed = po::parse_config_file(file, settings, false);
      po::store(parsed, values);
      AddSources(parsed, "'", "' in " + path, false, &sources);
    } catch (const po::error& e) {
      std::cerr << "reconduit-server: config file '" << path << "': " << e.what() << "\n";
      return 2;
    }
  }
  try {
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
    std::cerr << "reconduit-server: invalid configuration: " << error
              << SourceOf(sources, OptionOfField(error)) << "\n";
    return 2;
  }
  const std::pair<bool, const char*> limit_checks[] = {
      {limits.max_photos >= 1, "max-photos"},
      {limits.max_pixels >= 1, "max-pixels"},
      {limits.max_photo_bytes >= 1, "max-photo-bytes"},
      {limits.max_concurrent_uploads >= 1, "max-concurrent-uploads"},
      {limits.max_queued_jobs >= 1, "max-queued-jobs"},
      {lease_sweep_s >= 1, "lease-sweep-interval"}};
  for (const auto& [ok, option] : limit_checks) {
    if (!ok) {
      std::cerr << "reconduit-server: invalid configuration: " << option << " must be >= 1"
                << SourceOf(sources, option) << "\n";
      return 2;
    }
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
