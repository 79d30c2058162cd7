#include "server/http/test_client.h"

#include <boost/asio/connect.hpp>
#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>

#include <algorithm>
#include <cctype>
#include <sys/socket.h>
#include <sys/time.h>

namespace reconduit::server {

namespace beast = boost::beast;
namespace http = beast::http;
namespace net = boost::asio;
using tcp = net::ip::tcp;

std::string TestResponse::Header(std::string_view name) const {
  for (const auto& [key, value] : headers) {
    if (key.size() == name.size() &&
        std::equal(key.begin(), key.end(), name.begin(), [](char a, char b) {
          return std::tolower(static_cast<unsigned char>(a)) ==
                 std::tolower(static_cast<unsigned char>(b));
        })) {
      return value;
    }
  }
  return "";
}

struct TestClient::State {
  net::io_context ioc;
  tcp::socket socket{ioc};
  beast::flat_buffer buffer;
  bool connected = false;
};

TestClient::TestClient(int port,
                       std::chrono::milliseconds timeout,
                       const std::string& source_address)
    : state_(std::make_unique<State>()) {
  beast::error_code ec;
  if (!source_address.empty()) {
    state_->socket.open(tcp::v4(), ec);
    if (!ec) state_->socket.bind(tcp::endpoint(net::ip::make_address(source_address, ec), 0), ec);
    if (ec) return;
  }
  state_->socket.connect(
      tcp::endpoint(net::ip::make_address("127.0.0.1"), static_cast<unsigned short>(port)), ec);
  if (ec) return;
  timeval tv{};
  tv.tv_sec = static_cast<time_t>(timeout.count() / 1000);
  tv.tv_usec = static_cast<suseconds_t>((timeout.count() % 1000) * 1000);
  setsockopt(state_->socket.native_handle(), SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof(tv));
  setsockopt(state_->socket.native_handle(), SOL_SOCKET, SO_SNDTIMEO, &tv, sizeof(tv));
  state_->connected = true;
}

TestClient::~TestClient() {
  beast::error_code ec;
  state_->socket.shutdown(tcp::socket::shutdown_both, ec);
  state_->socket.close(ec);
}

bool TestClient::connected() const { return state_->connected; }

bool TestClient::Write(std::string_view bytes) {
  beast::error_code ec;
  net::write(state_->socket, net::buffer(bytes.data(), bytes.size()), ec);
  return !ec;
}

TestResponse TestClient::Read(bool head_response) {
  TestResponse result;
  http::response_parser<http::string_body> parser;
  parser.body_limit(64 * 1024 * 1024);
  parser.skip(head_response);
  beast::error_code ec;
  http::read(state_->socket, state_->buffer, parser, ec);
  if (ec) {
    result.error = ec.message();
    return result;
  }
  const auto& message = parser.get();
  result.status = message.result_int();
  for (const auto& field : message) {
    result.headers.emplace_back(std::string(field.name_string()), std::string(field.value()));
  }
  result.body = message.body();
  return result;
}

TestResponse TestClient::Request(std::string_view method,
                                 std::string_view target,
                                 const std::vector<std::pair<std::string, std::string>>& headers,
                                 std::string_view body) {
  std::string raw = std::string(method) + " " + std::string(target) + " HTTP/1.1\r\n";
  raw += "Host: 127.0.0.1\r\n";
  for (const auto& [name, value] : headers) raw += name + ": " + value + "\r\n";
  if (!body.empty() || method == "POST" || method == "PUT") {
    raw += "Content-Length: " + std::to_string(body.size()) + "\r\n";
  }
  raw += "\r\n";
  raw += body;
  if (!Write(raw)) {
    TestResponse result;
    result.error = "write failed";
    return result;
  }
  return Read();
}

bool TestClient::WaitForClose() {
  char byte[4096];
  while (true) {
    beast::error_code ec;
    state_->socket.read_some(net::buffer(byte), ec);
    if (ec == net::error::eof || ec == net::error::connection_reset) return true;
    // EAGAIN / would_block: the receive timeout expired with the connection still open.
    if (ec) return false;
  }
}

TestResponse Fetch(int port,
                   std::string_view method,
                   std::string_view target,
                   const std::vector<std::pair<std::string, std::string>>& headers,
                   std::string_view body) {
  TestClient client(port);
  if (!client.connected()) {
    TestResponse result;
    result.error = "cannot connect";
    return result;
  }
  return client.Request(method, target, headers, body);
}

}  // namespace reconduit::server
