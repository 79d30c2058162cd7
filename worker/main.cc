// reconduit-worker: claims queued jobs and runs the reconstruction pipeline on them.
//
// The job queue (server/storage) is not wired in yet, so this worker has nothing to claim:
// it says so once, then waits for SIGINT/SIGTERM. It never pretends to process photos.
#include <csignal>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <string>
#include <string_view>
#include <unistd.h>

namespace {

volatile std::sig_atomic_t g_stop = 0;
void OnSignal(int) { g_stop = 1; }

void PrintHelp() {
  std::cout << "Usage: reconduit-worker [--data DIR]\n"
               "  --data DIR   data folder shared with reconduit-server (env RECONDUIT_DATA,\n"
               "               default ./data)\n";
}

}  // namespace

int main(int argc, char** argv) {
  std::string data = std::getenv("RECONDUIT_DATA") ? std::getenv("RECONDUIT_DATA") : "data";
  for (int i = 1; i < argc; ++i) {
    const std::string_view arg(argv[i]);
    if (arg == "--help" || arg == "-h") {
      PrintHelp();
      return 0;
    } else if (arg == "--data" && i + 1 < argc) {
      data = argv[++i];
    } else {
      std::cerr << "reconduit-worker: unknown argument '" << arg << "' (see --help)\n";
      return 2;
    }
  }
  std::error_code ec;
  std::filesystem::create_directories(data, ec);
  if (ec) {
    std::cerr << "reconduit-worker: cannot create data folder '" << data << "': " << ec.message()
              << "\n";
    return 1;
  }
  std::signal(SIGINT, OnSignal);
  std::signal(SIGTERM, OnSignal);
  std::cout << "reconduit-worker: data folder " << std::filesystem::absolute(data).string()
            << "; the job queue is not implemented yet, so there is nothing to do" << std::endl;
  while (!g_stop) pause();
  std::cout << "reconduit-worker: stopped" << std::endl;
  return 0;
}
