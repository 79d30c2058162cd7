// A reconduit-server child process for integration tests: started on a free port (--port 0),
// its stdout read for the "listening on" line, its stderr written to a file.
#ifndef RECONDUIT_TESTS_SERVER_PROCESS_H_
#define RECONDUIT_TESTS_SERVER_PROCESS_H_

#include "server/http/test_client.h"

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <poll.h>
#include <signal.h>
#include <sstream>
#include <string>
#include <sys/wait.h>
#include <thread>
#include <unistd.h>
#include <vector>

extern char** environ;

namespace reconduit::testing_util {

class ServerProcess {
 public:
  explicit ServerProcess(std::string binary) : binary_(std::move(binary)) {}
  ServerProcess(const ServerProcess&) = delete;
  ServerProcess& operator=(const ServerProcess&) = delete;
  ~ServerProcess() {
    if (pid_ > 0 && !exited_) {
      ::kill(pid_, SIGKILL);
      int status = 0;
      ::waitpid(pid_, &status, 0);
    }
    if (stdout_fd_ >= 0) ::close(stdout_fd_);
  }

  // Starts the binary with `args` and extra "NAME=value" environment entries; waits up to 15 s
  // for the "listening on" line. False (the reason in error()) otherwise.
  bool Start(const std::vector<std::string>& args,
             const std::filesystem::path& stderr_path,
             const std::vector<std::string>& env = {}) {
    using namespace std::chrono_literals;
    stderr_path_ = stderr_path;
    std::vector<std::string> argv_strings = {binary_};
    argv_strings.insert(argv_strings.end(), args.begin(), args.end());
    std::vector<char*> argv;
    for (std::string& s : argv_strings) argv.push_back(s.data());
    argv.push_back(nullptr);
    std::vector<std::string> env_strings;
    for (char** e = environ; *e != nullptr; ++e) env_strings.emplace_back(*e);
    env_strings.insert(env_strings.end(), env.begin(), env.end());
    std::vector<char*> envp;
    for (std::string& s : env_strings) envp.push_back(s.data());
    envp.push_back(nullptr);
    int pipe_fds[2];
    if (::pipe(pipe_fds) != 0) return Fail("pipe failed");
    const std::string stderr_file = stderr_path.string();
    pid_ = ::fork();
    if (pid_ < 0) return Fail("fork failed");
    if (pid_ == 0) {
      ::dup2(pipe_fds[1], STDOUT_FILENO);
      ::close(pipe_fds[0]);
      ::close(pipe_fds[1]);
      FILE* err = std::fopen(stderr_file.c_str(), "a");
      if (err != nullptr) ::dup2(fileno(err), STDERR_FILENO);
      ::execve(argv[0], argv.data(), envp.data());
      ::_exit(127);
    }
    ::close(pipe_fds[1]);
    stdout_fd_ = pipe_fds[0];
    const std::string marker = "listening on http://127.0.0.1:";
    const auto deadline = std::chrono::steady_clock::now() + 15s;
    while (std::chrono::steady_clock::now() < deadline) {
      pollfd pfd{stdout_fd_, POLLIN, 0};
      if (::poll(&pfd, 1, 100) > 0) {
        char buffer[256];
        const ssize_t n = ::read(stdout_fd_, buffer, sizeof(buffer));
        if (n <= 0) break;
        stdout_.append(buffer, static_cast<std::size_t>(n));
        const std::size_t at = stdout_.find(marker);
        if (at != std::string::npos && stdout_.find('\n', at) != std::string::npos) {
          port_ = std::stoi(stdout_.substr(at + marker.size()));
          return true;
        }
      }
    }
    return Fail("no 'listening on' line; stdout: '" + stdout_ + "' stderr: '" + Stderr() + "'");
  }

  // SIGKILL and reap.
  void Kill() {
    if (pid_ <= 0 || exited_) return;
    ::kill(pid_, SIGKILL);
    int status = 0;
    ::waitpid(pid_, &status, 0);
    exited_ = true;
  }

  // SIGTERM; returns the exit status, or -1 when the process did not exit within `timeout`.
  int Terminate(std::chrono::milliseconds timeout) {
    Signal(SIGTERM);
    return WaitForExit(timeout);
  }

  void Signal(int signal) { ::kill(pid_, signal); }

  // Waits up to `timeout` for the process to exit; returns its exit status or -1.
  int WaitForExit(std::chrono::milliseconds timeout) {
    using namespace std::chrono_literals;
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    while (std::chrono::steady_clock::now() < deadline) {
      int status = 0;
      if (::waitpid(pid_, &status, WNOHANG) == pid_) {
        exited_ = true;
        return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
      }
      std::this_thread::sleep_for(10ms);
    }
    return -1;
  }

  // Polls GET /healthz for up to 4 s.
  bool WaitUntilHealthy() {
    using namespace std::chrono_literals;
    for (int i = 0; i < 200; ++i) {
      if (reconduit::server::Fetch(port_, "GET", "/healthz").status == 200) return true;
      std::this_thread::sleep_for(20ms);
    }
    return false;
  }

  std::string Stderr() const {
    std::ifstream in(stderr_path_);
    std::stringstream s;
    s << in.rdbuf();
    return s.str();
  }
  int port() const { return port_; }
  const std::string& stdout_text() const { return stdout_; }
  const std::string& error() const { return error_; }

 private:
  bool Fail(std::string message) {
    error_ = std::move(message);
    return false;
  }

  std::string binary_;
  pid_t pid_ = -1;
  bool exited_ = false;
  int stdout_fd_ = -1;
  int port_ = 0;
  std::string stdout_;
  std::string error_;
  std::filesystem::path stderr_path_;
};

}  // namespace reconduit::testing_util

#endif  // RECONDUIT_TESTS_SERVER_PROCESS_H_
