// Request counters kept by the transport for GET /metrics.
//
// The transport counts every response it starts to write (including refusals such as 401, 413
// and the 503 of a full server) by status code. Lock-free: one relaxed atomic per status.
//
// Thread-safety: all methods may be called from any thread.
#ifndef RECONDUIT_SERVER_HTTP_HTTP_METRICS_H_
#define RECONDUIT_SERVER_HTTP_HTTP_METRICS_H_

#include <array>
#include <atomic>
#include <cstdint>
#include <utility>
#include <vector>

namespace reconduit::server {

class HttpMetrics {
 public:
  // Counts one response with HTTP status `status`; codes outside [100, 599] are counted as 0.
  void CountResponse(unsigned status) {
    const unsigned index = status >= 100 && status < kSize ? status : 0;
    counts_[index].fetch_add(1, std::memory_order_relaxed);
  }

  // (status, count) for every status counted at least once, ascending by status.
  std::vector<std::pair<unsigned, std::uint64_t>> ResponsesByStatus() const {
    std::vector<std::pair<unsigned, std::uint64_t>> result;
    for (unsigned status = 0; status < kSize; ++status) {
      const std::uint64_t count = counts_[status].load(std::memory_order_relaxed);
      if (count > 0) result.emplace_back(status, count);
    }
    return result;
  }

 private:
  static constexpr unsigned kSize = 600;
  std::array<std::atomic<std::uint64_t>, kSize> counts_{};
};

}  // namespace reconduit::server

#endif  // RECONDUIT_SERVER_HTTP_HTTP_METRICS_H_
