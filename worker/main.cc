// reconduit-worker: claims queued jobs from the shared job store and runs the reconstruction
// pipeline on them, one at a time, until stopped. See worker/README.md. Settings: flags,
// environment, then the configuration file's top-level names and [worker] section
// (config/config.h).
#include "core/util/logging.h"
#include "worker/job_runner.h"
#include "worker/memory_budget.h"

#include "config/config.h"
#include "store/data_layout.h"
#include <atomic>
#include <cerrno>
#include <chrono>
#include <condition_variable>
#include <csignal>
#include <cstdlib>
#include <fcntl.h>
#include <filesystem>
#include <functional>
#include <iostream>
#include <malloc.h>
#include <mutex>
#include <optional>
#include <poll.h>
#include <random>
#include <string>
#include <thread>
#include <unistd.h>
#include <vector>

namespace reconduit {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;

constexpr char kUsage[] =
    "Usage: reconduit-worker [options]\n"
    "\n"
    "Claims the oldest queued job in <data>/reconduit.db, runs the reconstruction pipeline on\n"
    "it (resuming after the stages an earlier run finished), records progress and events, and\n"
    "finishes it; then the next. Run as many workers side by side as the machine allows: each\n"
    "job goes to exactly one of them. Settings come from the flags, the environment variables\n"
    "named below, and the configuration file given by --config: 'name = value' lines at the\n"
    "top or under [worker] (the flag names without '--'; 'once = true').\n";

constexpr char kEpilogue[] =
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
  // MiB; 0 = DefaultMemoryBudgetBytes(), -1 = none.
  std::int64_t memory_budget_mib = 0;
  double stop_timeout_seconds = 10.0;
  std::string until;
  bool once = false;
};

// The option table, bound to the fields of *flags, with the worker's environment variables.
config::ProgramSettings WorkerProgram(Flags* flags) {
  namespace po = boost::program_options;
  config::ProgramSettings program;
  program.program = "reconduit-worker";
  program.section = "worker";
  program.usage = kUsage;
  program.epilogue = kEpilogue;
  // clang-format off
  program.options.add_options()
      ("data", po::value(&flags->data)->value_name("DIR")->default_value(flags->data),
       "Data folder shared with reconduit-server (env RECONDUIT_DATA). Created if missing.")
      ("id", po::value(&flags->id)->value_name("NAME"),
       "This worker's name in the job store (env RECONDUIT_WORKER_ID; default "
       "<host>:<pid>:<random>). Must be unique among workers.")
      ("lease", po::value(&flags->lease_seconds)->value_name("SECONDS")->default_value(flags->lease_seconds),
       "Seconds a claimed job stays ours without a heartbeat (env RECONDUIT_LEASE_SECONDS; "
       "0.3-86400). Heartbeats run every lease/3; a crashed worker's job is requeued when it "
       "expires.")
      ("poll", po::value(&flags->poll_seconds)->value_name("SECONDS")->default_value(flags->poll_seconds),
       "Seconds between looks at an empty queue (env RECONDUIT_POLL_SECONDS).")
      ("threads", po::value(&flags->threads)->value_name("N")->default_value(flags->threads),
       "Threads per job, the most a job may use: a job's num_threads option may ask for "
       "fewer, never more (env RECONDUIT_WORKER_THREADS; 0 = all cores, at most 256).")
      ("memory-budget",
       po::value(&flags->memory_budget_mib)->value_name("MIB")->default_value(flags->memory_budget_mib),
       "The most resident memory a job may hold, in MiB (env RECONDUIT_WORKER_MEMORY_BUDGET): "
       "a job that goes over it fails with a message naming the stage, and the worker takes the "
       "next job. 0 = three quarters of the machine's memory (or of the cgroup's limit); -1 = "
       "no budget. Give each of several workers on one machine its share.")
      ("until", po::value(&flags->until)->value_name("STAGE"),
       "Run the stages up to this one, then pack the results (env RECONDUIT_UNTIL_STAGE; "
       "default: every stage). For deployments that want only the early stages; jobs still "
       "succeed, with what those stages produce.")
      ("stop-timeout",
       po::value(&flags->stop_timeout_seconds)->value_name("SECONDS")->default_value(flags->stop_timeout_seconds),
       "On SIGTERM/SIGINT, seconds to wait for the running stage to stop before giving the "
       "job back anyway and exiting (env RECONDUIT_STOP_TIMEOUT_SECONDS).")
      ("once", po::bool_switch(&flags->once),
       "Run at most one job (none if the queue is empty), then exit.");
  // clang-format on
  program.environment = {{"data", "RECONDUIT_DATA"},
                         {"id", "RECONDUIT_WORKER_ID"},
                         {"lease", "RECONDUIT_LEASE_SECONDS"},
                         {"poll", "RECONDUIT_POLL_SECONDS"},
                         {"threads", "RECONDUIT_WORKER_THREADS"},
                         {"memory-budget", "RECONDUIT_WORKER_MEMORY_BUDGET"},
                         {"until", "RECONDUIT_UNTIL_STAGE"},
                         {"stop-timeout", "RECONDUIT_STOP_TIMEOUT_SECONDS"}};
  return program;
}

// The ranges the types do not express; the first problem, or "".
std::string CheckFlags(const config::Settings& settings, const Flags& flags) {
  const auto seconds_ok = [](double s) { return s > 0.0 && s <= 86400.0; };
  if (flags.data.empty()) return settings.Invalid("data", "must not be empty");
  if (settings.values.count("id") != 0 && (flags.id.empty() || flags.id.size() > 200)) {
    return settings.Invalid("id", "must have 1 to 200 characters");
  }
  if (!seconds_ok(flags.lease_seconds) || flags.lease_seconds < 0.3) {
    return settings.Invalid("lease", "must be in [0.3, 86400] seconds");
  }
  if (!seconds_ok(flags.poll_seconds)) {
    return settings.Invalid("poll", "must be in (0, 86400] seconds");
  }
  if (!seconds_ok(flags.stop_timeout_seconds)) {
    return settings.Invalid("stop-timeout", "must be in (0, 86400] seconds");
  }
  if (flags.threads < 0 || flags.threads > 256) {
    return settings.Invalid("threads", "must be in [0, 256]");
  }
  if (flags.memory_budget_mib < -1 ||
      (flags.memory_budget_mib > 0 && flags.memory_budget_mib < 64) ||
      flags.memory_budget_mib > (std::int64_t{1} << 30)) {
    return settings.Invalid("memory-budget", "must be -1 (none), 0 (automatic) or 64 MiB and up");
  }
  if (settings.values.count("until") != 0) {
    if (const Status known = CheckUntilStage(flags.until); !known.ok()) {
      return settings.Invalid("until", known.message());
    }
  }
  return "";
}

// Flags over environment over the config file over defaults. Returns an exit status when the
// program should stop.
std::optional<int> ParseFlags(int argc, char** argv, Flags* flags) {
  const config::ProgramSettings program = WorkerProgram(flags);
  config::Settings settings;
  if (const std::optional<int> status =
          config::ParseSettings(program, std::vector<std::string>(argv + 1, argv + argc), &settings,
                                std::cout, std::cerr)) {
    return status;
  }
  if (const std::string error = CheckFlags(settings, *flags); !error.empty()) {
    std::cerr << "reconduit-worker: " << error << "\n";
    return 2;
  }
  if (flags->id.empty()) flags->id = DefaultWorkerId();
  return std::nullopt;
}

// SIGTERM/SIGINT: the handler only writes the signal number to a pipe (async-signal-safe); a
// normal thread reads it and does the work (SignalWatcher). sigwait() in a thread would not do:
// libraries start threads before main() (OpenBLAS's pool), and the kernel may deliver the signal
// to one of them, whose mask we cannot set.
bool InstallSignalHandlers() {
  if (pipe2(g_signal_pipe, O_CLOEXEC | O_NONBLOCK) != 0) return false;
  struct sigaction action {};
  action.sa_handler = OnSignal;
  sigemptyset(&action.sa_mask);
  action.sa_flags = SA_RESTART;
  sigaction(SIGINT, &action, nullptr);
  sigaction(SIGTERM, &action, nullptr);
  return true;
}

// The data folder's job store; null after printing why not.
std::unique_ptr<JobStore> OpenStore(const DataLayout& layout) {
  std::error_code ec;
  fs::create_directories(layout.JobsDir(), ec);
  if (ec) {
    std::cerr << "reconduit-worker: cannot create the data folder " << layout.root().string()
              << ": " << ec.message() << "\n";
    return nullptr;
  }
  Result<std::unique_ptr<JobStore>> opened = OpenSqliteJobStore(layout.DatabasePath().string());
  if (!opened.ok()) {
    std::cerr << "reconduit-worker: cannot open the job store " << layout.DatabasePath().string()
              << ": " << opened.status() << "\n";
    return nullptr;
  }
  return std::move(opened).value();
}

// Crash-safety tests only: SIGKILL ourselves at a named moment (JobRunnerOptions::on_moment, or
// "claimed": right after a claim, before the job starts), deterministically where an outside
// kill -9 could not aim. Does nothing unless RECONDUIT_WORKER_CRASH_AT names a moment.
std::function<void(const std::string&)> CrashAtMoment() {
  const char* variable = std::getenv("RECONDUIT_WORKER_CRASH_AT");
  const std::string crash_at = variable != nullptr ? variable : "";
  if (crash_at.empty()) return {};
  return [crash_at](const std::string& moment) {
    if (moment != crash_at) return;
    std::cerr << "reconduit-worker: RECONDUIT_WORKER_CRASH_AT=" << crash_at
              << " reached: killing this process" << std::endl;
    kill(getpid(), SIGKILL);
  };
}

JobRunnerOptions RunnerOptions(const Flags& flags, const DataLayout& layout) {
  JobRunnerOptions options;
  options.data_dir = layout.root();
  options.worker_id = flags.id;
  options.lease = ToMillis(flags.lease_seconds);
  options.default_num_threads = flags.threads;
  options.memory_budget_bytes = flags.memory_budget_mib == 0  ? DefaultMemoryBudgetBytes()
                                : flags.memory_budget_mib < 0 ? 0
                                                              : flags.memory_budget_mib << 20;
  options.make_stages = StagesUntil(flags.until);
  options.on_moment = CrashAtMoment();
  // A cancel request should be seen within a second, but never more often than a few beats
  // per lease.
  options.cancel_check_interval = std::min(1000ms, options.lease / 4);
  return options;
}

void SweepStoppedWorkers(JobStore& store) {
  if (Result<SweepResult> swept = store.SweepExpiredLeases(); !swept.ok()) {
    LOG_WARNING << "cannot sweep expired leases: " << swept.status();
  } else if (swept->requeued + swept->failed + swept->canceled > 0) {
    LOG_INFO << "jobs of stopped workers: " << swept->requeued << " requeued, " << swept->failed
             << " failed (out of attempts), " << swept->canceled << " canceled";
  }
}

// The state the claim loop and the signal thread share.
struct StopState {
  std::mutex mutex;
  std::condition_variable wake;
  std::atomic<bool> stop{false};
  std::atomic<bool> finished{false};
};

// The signal thread's body: the first signal asks the runner to stop and wakes the claim loop;
// when the stage has not stopped `stop_timeout` later (or at a second signal) the job is handed
// back and the process exits. Returns when state->finished is set.
void WatchSignals(JobRunner& runner, std::chrono::milliseconds stop_timeout, StopState* state) {
  std::optional<std::chrono::steady_clock::time_point> deadline;
  while (!state->finished) {
    pollfd readable{g_signal_pipe[0], POLLIN, 0};
    unsigned char signal = 0;
    if (poll(&readable, 1, 100) == 1 && read(g_signal_pipe[0], &signal, 1) == 1) {
      if (!state->stop.exchange(true)) {
        LOG_INFO << "signal " << static_cast<int>(signal)
                 << ": stopping; the running job goes back to the queue";
        runner.RequestStop();
        { std::lock_guard lock(state->mutex); }
        state->wake.notify_all();
        deadline = std::chrono::steady_clock::now() + stop_timeout;
      } else {
        deadline = std::chrono::steady_clock::now();  // Second signal: do not wait.
      }
    }
    if (deadline && !state->finished && std::chrono::steady_clock::now() >= *deadline) {
      // The stage did not notice the cancel in time: hand the job back and leave. The next
      // worker starts the interrupted stage over.
      const Status released = runner.ReleaseRunningJobNow();
      LOG_WARNING << "the running stage did not stop in time; "
                  << (released.ok() ? "job released" : released.ToString()) << "; exiting";
      std::_Exit(0);
    }
  }
}

// Claims and runs jobs until stopped (or after one look with --once).
void ClaimLoop(const Flags& flags,
               const JobRunnerOptions& options,
               JobStore& store,
               JobRunner& runner,
               StopState* state) {
  bool announced_waiting = false;
  const auto poll_interval = ToMillis(flags.poll_seconds);
  while (!state->stop) {
    Result<std::optional<Job>> claimed = store.ClaimNextJob(flags.id, options.lease);
    if (!claimed.ok()) {
      LOG_WARNING << "cannot claim a job: " << claimed.status() << "; retrying";
    } else if (claimed->has_value()) {
      announced_waiting = false;
      const Job& job = **claimed;
      if (options.on_moment) options.on_moment("claimed");
      const JobRunReport report = runner.Run(job);
      LOG_INFO << "job " << job.id << ": " << JobRunOutcomeName(report.outcome) << " in "
               << report.seconds << " s"
               << (report.message.empty() ? "" : " (" + report.stage + ": " + report.message + ")");
      // Give the job's freed heap back to the system: what glibc keeps would count against the
      // next job's memory budget.
      malloc_trim(0);
      if (flags.once) break;
      continue;
    } else {
      if (!announced_waiting) {
        LOG_INFO << "waiting for jobs";
        announced_waiting = true;
      }
      if (flags.once) break;
    }
    std::unique_lock lock(state->mutex);
    state->wake.wait_for(lock, poll_interval, [&] { return state->stop.load(); });
  }
}

int Main(int argc, char** argv) {
  Flags flags;
  if (const auto status = ParseFlags(argc, argv, &flags)) return *status;
  if (!InstallSignalHandlers()) {
    std::cerr << "reconduit-worker: cannot create the signal pipe\n";
    return 1;
  }
  const DataLayout layout(flags.data);
  const std::unique_ptr<JobStore> store = OpenStore(layout);
  if (store == nullptr) return 1;
  const JobRunnerOptions options = RunnerOptions(flags, layout);
  JobRunner runner(*store, options);

  LOG_INFO << "reconduit-worker " << flags.id << ": data folder "
           << fs::absolute(layout.root()).string() << ", lease " << flags.lease_seconds << " s"
           << (flags.until.empty() ? "" : ", stages up to " + flags.until) << ", memory budget "
           << (options.memory_budget_bytes > 0 ? FormatMemory(options.memory_budget_bytes)
                                               : std::string("none"));
  SweepStoppedWorkers(*store);

  StopState state;
  std::thread signal_thread(
      [&] { WatchSignals(runner, ToMillis(flags.stop_timeout_seconds), &state); });
  ClaimLoop(flags, options, *store, runner, &state);
  state.finished = true;
  signal_thread.join();
  LOG_INFO << "reconduit-worker " << flags.id << ": stopped";
  return 0;
}

}  // namespace
}  // namespace reconduit

int main(int argc, char** argv) {
  // A write over a file size limit (RLIMIT_FSIZE) must fail the stage with EFBIG, like a full
  // disk, not kill the worker with SIGXFSZ.
  std::signal(SIGXFSZ, SIG_IGN);
  try {
    return reconduit::Main(argc, argv);
  } catch (const std::exception& e) {
    std::cerr << "reconduit-worker: " << e.what() << "\n";
    return 1;
  }
}
