// reconduit-worker: claims queued jobs from the shared job store and runs the reconstruction
// pipeline on them, one at a time, until stopped. See worker/README.md.
#include "core/util/logging.h"
#include "worker/job_runner.h"

#include <boost/program_options/errors.hpp>
#include <boost/program_options/options_description.hpp>
#include <boost/program_options/parsers.hpp>

#include "store/data_layout.h"
#include <atomic>
#include <cerrno>
#include <chrono>
#include <condition_variable>
#include <csignal>
#include <cstdlib>
#include <cstring>
#include <fcntl.h>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iostream>
#include <mutex>
#include <optional>
#include <poll.h>
#include <random>
#include <set>
#include <string>
#include <string_view>
#include <thread>
#include <unistd.h>
#include <vector>

namespace reconduit {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;

constexpr char kUsage[] =
    "Usage: reconduit-worker [--config FILE] [--data DIR] [--id NAME] [--lease SECONDS]\n"
    "                        [--poll SECONDS] [--threads N] [--until STAGE]\n"
    "                        [--stop-timeout SECONDS] [--once]\n"
    "\n"
    "Claims the oldest queued job in <data>/reconduit.db, runs the reconstruction pipeline on\n"
    "it (resuming after the stages an earlier run finished), records progress and events, and\n"
    "finishes it; then the next. Run as many workers side by side as the machine allows: each\n"
    "job goes to exactly one of them.\n"
    "\n"
    "  --config FILE          read settings from FILE (env RECONDUIT_CONFIG): INI-style\n"
    "                         'name = value' lines with the long flag names without '--'\n"
    "                         (data, id, lease, poll, threads, until, stop-timeout, once =\n"
    "                         true|false); '#' starts a comment. An unknown name or a bad\n"
    "                         value is an error (exit status 2).\n"
    "  --data DIR             data folder shared with reconduit-server (env RECONDUIT_DATA;\n"
    "                         default ./data). Created if missing.\n"
    "  --id NAME              this worker's name in the job store (env RECONDUIT_WORKER_ID;\n"
    "                         default <host>:<pid>:<random>). Must be unique among workers.\n"
    "  --lease SECONDS        how long a claimed job stays ours without a heartbeat (env\n"
    "                         RECONDUIT_LEASE_SECONDS; default 60). Heartbeats run every\n"
    "                         lease/3; a crashed worker's job is requeued when it expires.\n"
    "  --poll SECONDS         pause between looks at an empty queue (env\n"
    "                         RECONDUIT_POLL_SECONDS; default 1).\n"
    "  --threads N            threads per job when the job's options do not set num_threads\n"
    "                         (env RECONDUIT_WORKER_THREADS; default 0 = all cores).\n"
    "  --until STAGE          run the stages up to STAGE, then pack the results (env\n"
    "                         RECONDUIT_UNTIL_STAGE; default: every stage). For deployments\n"
    "                         that want only the early stages; jobs still succeed, with what\n"
    "                         those stages produce.\n"
    "  --stop-timeout SECONDS on SIGTERM/SIGINT, how long to wait for the running stage to\n"
    "                         stop before giving the job back anyway and exiting (env\n"
    "                         RECONDUIT_STOP_TIMEOUT_SECONDS; default 10).\n"
    "  --once                 run at most one job (none if the queue is empty), then exit.\n"
    "  --help                 this text.\n"
    "\n"
    "Precedence: command line > environment > config file > defaults.\n"
    "Log level: env RECONDUIT_LOG_LEVEL=debug|info|warning|error (default info).\n"
    "Signals: SIGTERM or SIGINT stops claiming, cancels the running job's stage and gives the\n"
    "job back to the queue (it resumes on the next worker); exit status 0. A second signal\n"
    "gives the job back at once without waiting for the stage.\n"
    "Exit status: 0 stopped normally, 1 cannot open the data folder or the job store, 2 bad\n"
    "command line, environment or config file.\n";

// Written by the signal handler, read by the signal thread.
int g_signal_pipe[2] = {-1, -1};

void OnSignal(int signal) {
  const int saved_errno = errno;
  const unsigned char byte = static_cast<unsigned char>(signal);
  [[maybe_unused]] const ssize_t written = write(g_signal_pipe[1], &byte, 1);
  errno = saved_errno;
}

int UsageError(const std::string& message) {
  std::cerr << "reconduit-worker: " << message << " (see --help)\n";
  return 2;
}

std::optional<double> ParseSeconds(const std::string& text) {
  try {
    std::size_t used = 0;
    const double value = std::stod(text, &used);
    if (used != text.size() || !(value > 0.0) || value > 86400.0) return std::nullopt;
    return value;
  } catch (const std::exception&) {
    return std::nullopt;
  }
}

std::optional<int> ParseCount(const std::string& text, int max) {
  try {
    std::size_t used = 0;
    const int value = std::stoi(text, &used);
    if (used != text.size() || value < 0 || value > max) return std::nullopt;
    return value;
  } catch (const std::exception&) {
    return std::nullopt;
  }
}

std::chrono::milliseconds ToMillis(double seconds) {
  return std::chrono::milliseconds(static_cast<std::int64_t>(seconds * 1000.0 + 0.5));
}

std::string DefaultWorkerId() {
  char host[256] = {};
  if (gethostname(host, sizeof(host) - 1) != 0) host[0] = '\0';
  std::random_device device;
  char suffix[16];
  std::snprintf(suffix, sizeof(suffix), "%08x", device());
  return std::string(host[0] ? host : "worker") + ":" + std::to_string(getpid()) + ":" + suffix;
}

struct Flags {
  std::string data = "data";
  std::string id;
  double lease_seconds = 60.0;
  double poll_seconds = 1.0;
  int threads = 0;
  double stop_timeout_seconds = 10.0;
  std::string until;
  bool once = false;
};

std::optional<bool> ParseBool(const std::string& text) {
  if (text == "true" || text == "1" || text == "yes" || text == "on") return true;
  if (text == "false" || text == "0" || text == "no" || text == "off") return false;
  return std::nullopt;
}

// Flags over environment over the config file over defaults. Returns an exit status when the
// program should stop.
std::optional<int> ParseFlags(int argc, char** argv, Flags* flags) {
  auto env = [](const char* name) -> std::optional<std::string> {
    const char* value = std::getenv(name);
    if (value == nullptr || *value == '\0') return std::nullopt;
    return std::string(value);
  };
  struct Setting {
    std::string flag;
    const char* env;
    std::function<bool(const std::string&)> set;
  };
  const std::vector<Setting> settings = {
      {"--data", "RECONDUIT_DATA",
       [&](const std::string& v) {
         flags->data = v;
         return !v.empty();
       }},
      {"--id", "RECONDUIT_WORKER_ID",
       [&](const std::string& v) {
         flags->id = v;
         return !v.empty() && v.size() <= 200;
       }},
      {"--lease", "RECONDUIT_LEASE_SECONDS",
       [&](const std::string& v) {
         const auto s = ParseSeconds(v);
         if (s && *s >= 0.3) flags->lease_seconds = *s;
         return s && *s >= 0.3;
       }},
      {"--poll", "RECONDUIT_POLL_SECONDS",
       [&](const std::string& v) {
         const auto s = ParseSeconds(v);
         if (s) flags->poll_seconds = *s;
         return s.has_value();
       }},
      {"--threads", "RECONDUIT_WORKER_THREADS",
       [&](const std::string& v) {
         const auto n = ParseCount(v, 256);
         if (n) flags->threads = *n;
         return n.has_value();
       }},
      {"--until", "RECONDUIT_UNTIL_STAGE",
       [&](const std::string& v) {
         flags->until = v;
         const Status known = CheckUntilStage(v);
         if (!known.ok()) std::cerr << "reconduit-worker: " << known.message() << "\n";
         return known.ok();
       }},
      {"--stop-timeout", "RECONDUIT_STOP_TIMEOUT_SECONDS",
       [&](const std::string& v) {
         const auto s = ParseSeconds(v);
         if (s) flags->stop_timeout_seconds = *s;
         return s.has_value();
       }},
  };

  // --help and --config first: help needs no valid settings, and the file is read before the
  // environment and the flags, which override it.
  std::optional<std::string> config_path = env("RECONDUIT_CONFIG");
  for (int i = 1; i < argc; ++i) {
    const std::string arg(argv[i]);
    if (arg == "--help" || arg == "-h") {
      std::cout << kUsage;
      return 0;
    }
    if (arg == "--config") {
      if (i + 1 >= argc) return UsageError("--config needs a value");
      config_path = argv[++i];
    }
  }
  if (config_path) {
    const std::string& path = *config_path;
    std::ifstream file(path);
    if (!file) {
      std::cerr << "reconduit-worker: cannot read the config file '" << path
                << "': " << std::strerror(errno) << "\n";
      return 2;
    }
    namespace po = boost::program_options;
    po::options_description keys;
    for (const Setting& setting : settings) {
      keys.add_options()(setting.flag.substr(2).c_str(), po::value<std::string>());
    }
    keys.add_options()("once", po::value<std::string>());
    const std::string where = "reconduit-worker: config file '" + path + "': ";
    try {
      // Unknown names (a typo, "config", a [section]) are errors, never ignored.
      const po::parsed_options parsed = po::parse_config_file(file, keys, false);
      std::set<std::string> seen;
      for (const po::option& option : parsed.options) {
        const std::string& key = option.string_key;
        const std::string value = option.value.empty() ? "" : option.value.front();
        if (!seen.insert(key).second) {
          std::cerr << where << "'" << key << "' is set more than once\n";
          return 2;
        }
        bool valid = false;
        if (key == "once") {
          const std::optional<bool> once = ParseBool(value);
          if (once) flags->once = *once;
          valid = once.has_value();
        } else {
          for (const Setting& setting : settings) {
            if (setting.flag.substr(2) == key) valid = setting.set(value);
          }
        }
        if (!valid) {
          std::cerr << where << "invalid value '" << value << "' for '" << key << "'\n";
          return 2;
        }
      }
    } catch (const po::error& e) {
      std::cerr << where << e.what() << "\n";
      return 2;
    }
  }
  for (const Setting& setting : settings) {
    if (const auto value = env(setting.env); value && !setting.set(*value)) {
      std::cerr << "reconduit-worker: invalid " << setting.env << "='" << *value << "'\n";
      return 2;
    }
  }
  for (int i = 1; i < argc; ++i) {
    const std::string arg(argv[i]);
    if (arg == "--config") {
      ++i;  // Read above.
      continue;
    }
    if (arg == "--once") {
      flags->once = true;
      continue;
    }
    bool known = false;
    for (const Setting& setting : settings) {
      if (arg != setting.flag) continue;
      known = true;
      if (i + 1 >= argc) return UsageError(arg + " needs a value");
      const std::string value(argv[++i]);
      if (!setting.set(value)) return UsageError("invalid value '" + value + "' for " + arg);
    }
    if (!known) return UsageError("unknown argument '" + arg + "'");
  }
  if (flags->id.empty()) flags->id = DefaultWorkerId();
  return std::nullopt;
}

int Main(int argc, char** argv) {
  Flags flags;
  if (const auto status = ParseFlags(argc, argv, &flags)) return *status;

  // SIGTERM/SIGINT: the handler only writes the signal number to a pipe (async-signal-safe);
  // a normal thread reads it and does the work. sigwait() in a thread would not do: libraries
  // start threads before main() (OpenBLAS's pool), and the kernel may deliver the signal to one
  // of them, whose mask we cannot set.
  if (pipe2(g_signal_pipe, O_CLOEXEC | O_NONBLOCK) != 0) {
    std::cerr << "reconduit-worker: cannot create the signal pipe\n";
    return 1;
  }
  struct sigaction action {};
  action.sa_handler = OnSignal;
  sigemptyset(&action.sa_mask);
  action.sa_flags = SA_RESTART;
  sigaction(SIGINT, &action, nullptr);
  sigaction(SIGTERM, &action, nullptr);

  const DataLayout layout(flags.data);
  std::error_code ec;
  fs::create_directories(layout.JobsDir(), ec);
  if (ec) {
    std::cerr << "reconduit-worker: cannot create the data folder " << layout.root().string()
              << ": " << ec.message() << "\n";
    return 1;
  }
  Result<std::unique_ptr<JobStore>> opened = OpenSqliteJobStore(layout.DatabasePath().string());
  if (!opened.ok()) {
    std::cerr << "reconduit-worker: cannot open the job store " << layout.DatabasePath().string()
              << ": " << opened.status() << "\n";
    return 1;
  }
  std::unique_ptr<JobStore> store = std::move(opened).value();

  JobRunnerOptions options;
  options.data_dir = layout.root();
  options.worker_id = flags.id;
  options.lease = ToMillis(flags.lease_seconds);
  options.default_num_threads = flags.threads;
  options.make_stages = StagesUntil(flags.until);
  // Crash-safety tests only: SIGKILL ourselves at a named moment (JobRunnerOptions::on_moment,
  // or "claimed": right after a claim, before the job starts), deterministically where an
  // outside kill -9 could not aim.
  const std::string crash_at = std::getenv("RECONDUIT_WORKER_CRASH_AT") != nullptr
                                   ? std::getenv("RECONDUIT_WORKER_CRASH_AT")
                                   : "";
  auto crash_if = [crash_at](const std::string& moment) {
    if (crash_at.empty() || moment != crash_at) return;
    std::cerr << "reconduit-worker: RECONDUIT_WORKER_CRASH_AT=" << crash_at
              << " reached: killing this process" << std::endl;
    kill(getpid(), SIGKILL);
  };
  if (!crash_at.empty()) options.on_moment = crash_if;
  // A cancel request should be seen within a second, but never more often than a few beats
  // per lease.
  options.cancel_check_interval = std::min(1000ms, options.lease / 4);
  JobRunner runner(*store, options);

  LOG_INFO << "reconduit-worker " << flags.id << ": data folder "
           << fs::absolute(layout.root()).string() << ", lease " << flags.lease_seconds << " s"
           << (flags.until.empty() ? "" : ", stages up to " + flags.until);
  if (Result<SweepResult> swept = store->SweepExpiredLeases(); !swept.ok()) {
    LOG_WARNING << "cannot sweep expired leases: " << swept.status();
  } else if (swept->requeued + swept->failed + swept->canceled > 0) {
    LOG_INFO << "jobs of stopped workers: " << swept->requeued << " requeued, " << swept->failed
             << " failed (out of attempts), " << swept->canceled << " canceled";
  }

  std::mutex mutex;
  std::condition_variable wake;
  std::atomic<bool> stop{false};
  std::atomic<bool> finished{false};
  const auto stop_timeout = ToMillis(flags.stop_timeout_seconds);

  std::thread signal_thread([&] {
    std::optional<std::chrono::steady_clock::time_point> deadline;
    while (!finished) {
      pollfd readable{g_signal_pipe[0], POLLIN, 0};
      unsigned char signal = 0;
      if (poll(&readable, 1, 100) == 1 && read(g_signal_pipe[0], &signal, 1) == 1) {
        if (!stop.exchange(true)) {
          LOG_INFO << "signal " << static_cast<int>(signal)
                   << ": stopping; the running job goes back to the queue";
          runner.RequestStop();
          { std::lock_guard lock(mutex); }
          wake.notify_all();
          deadline = std::chrono::steady_clock::now() + stop_timeout;
        } else {
          deadline = std::chrono::steady_clock::now();  // Second signal: do not wait.
        }
      }
      if (deadline && !finished && std::chrono::steady_clock::now() >= *deadline) {
        // The stage did not notice the cancel in time: hand the job back and leave. The next
        // worker starts the interrupted stage over.
        const Status released = runner.ReleaseRunningJobNow();
        LOG_WARNING << "the running stage did not stop in time; "
                    << (released.ok() ? "job released" : released.ToString()) << "; exiting";
        std::_Exit(0);
      }
    }
  });

  bool announced_waiting = false;
  const auto poll_interval = ToMillis(flags.poll_seconds);
  while (!stop) {
    Result<std::optional<Job>> claimed = store->ClaimNextJob(flags.id, options.lease);
    if (!claimed.ok()) {
      LOG_WARNING << "cannot claim a job: " << claimed.status() << "; retrying";
    } else if (claimed->has_value()) {
      announced_waiting = false;
      const Job& job = **claimed;
      crash_if("claimed");
      const JobRunReport report = runner.Run(job);
      LOG_INFO << "job " << job.id << ": " << JobRunOutcomeName(report.outcome) << " in "
               << report.seconds << " s"
               << (report.message.empty() ? "" : " (" + report.stage + ": " + report.message + ")");
      if (flags.once) break;
      continue;
    } else {
      if (!announced_waiting) {
        LOG_INFO << "waiting for jobs";
        announced_waiting = true;
      }
      if (flags.once) break;
    }
    std::unique_lock lock(mutex);
    wake.wait_for(lock, poll_interval, [&] { return stop.load(); });
  }
  finished = true;
  signal_thread.join();
  LOG_INFO << "reconduit-worker " << flags.id << ": stopped";
  return 0;
}

}  // namespace
}  // namespace reconduit

int main(int argc, char** argv) {
  try {
    return reconduit::Main(argc, argv);
  } catch (const std::exception& e) {
    std::cerr << "reconduit-worker: " << e.what() << "\n";
    return 1;
  }
}
