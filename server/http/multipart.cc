#include "server/http/multipart.h"

#include <utility>

namespace reconduit::server {
namespace {

constexpr std::string_view kCrlf = "\r\n";
// RFC 2046 allows linear white space after a boundary; bound it so it cannot grow forever.
constexpr std::size_t kMaxTransportPadding = 256;
constexpr std::size_t kMaxBoundaryLength = 70;

std::string_view Trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t')) s.remove_suffix(1);
  return s;
}

Status Malformed(std::string message) {
  return Status::InvalidArgument("malformed multipart body: " + std::move(message));
}

}  // namespace

Result<std::string> MultipartBoundary(std::string_view content_type) {
  Result<HeaderValue> parsed = ParseHeaderValue(content_type);
  if (!parsed.ok()) return parsed.status();
  if (parsed->value != "multipart/form-data") {
    return Status::InvalidArgument("expected Content-Type multipart/form-data, got '" +
                                   std::string(content_type) + "'");
  }
  std::optional<std::string> boundary = parsed->Param("boundary");
  if (!boundary || boundary->empty()) {
    return Status::InvalidArgument("multipart/form-data Content-Type without a boundary");
  }
  if (boundary->size() > kMaxBoundaryLength) {
    return Status::InvalidArgument("multipart boundary longer than 70 characters");
  }
  if (boundary->find_first_of("\r\n") != std::string::npos) {
    return Status::InvalidArgument("multipart boundary contains a line break");
  }
  return *std::move(boundary);
}

MultipartParser::MultipartParser(std::string boundary, Callbacks callbacks)
    : MultipartParser(std::move(boundary), std::move(callbacks), Options()) {}

MultipartParser::MultipartParser(std::string boundary, Callbacks callbacks, Options options)
    : delimiter_("\r\n--" + boundary),
      callbacks_(std::move(callbacks)),
      options_(options),
      // The first delimiter may open the body without a CRLF before it: pretend one was seen,
      // so a single search for "\r\n--boundary" finds every delimiter.
      buffer_(kCrlf) {
  THROW_CHECK(!boundary.empty()) << "empty multipart boundary";
}

Status MultipartParser::Feed(std::string_view chunk) {
  if (state_ == State::kFailed) return error_;
  if (state_ == State::kEpilogue) return Status::Ok();
  buffer_.append(chunk);
  return Process();
}

Status MultipartParser::Finish() {
  if (state_ == State::kFailed) return error_;
  if (state_ == State::kEpilogue) return Status::Ok();
  return Fail(Malformed("the body ended before the closing boundary (truncated upload?)"));
}

Status MultipartParser::Fail(Status status) {
  state_ = State::kFailed;
  error_ = std::move(status);
  buffer_.clear();
  buffer_.shrink_to_fit();
  return error_;
}

Status MultipartParser::Process() {
  while (true) {
    switch (state_) {
      case State::kPreamble: {
        const std::size_t pos = buffer_.find(delimiter_);
        if (pos == std::string::npos) {
          // Keep only what could be the start of a delimiter split across chunks.
          const std::size_t keep = delimiter_.size() - 1;
          if (buffer_.size() > keep) buffer_.erase(0, buffer_.size() - keep);
          return Status::Ok();
        }
        buffer_.erase(0, pos + delimiter_.size());
        state_ = State::kAfterDelimiter;
        break;
      }

      case State::kAfterDelimiter: {
        if (buffer_.size() < 2) return Status::Ok();
        if (buffer_[0] == '-' && buffer_[1] == '-') {
          state_ = State::kEpilogue;
          buffer_.clear();
          return Status::Ok();
        }
        std::size_t i = 0;
        while (i < buffer_.size() && (buffer_[i] == ' ' || buffer_[i] == '\t')) ++i;
        if (i > kMaxTransportPadding) return Fail(Malformed("too much padding after a boundary"));
        if (i < buffer_.size() && buffer_[i] != '\r') {
          return Fail(Malformed("unexpected characters after a boundary"));
        }
        if (buffer_.size() < i + 2) return Status::Ok();
        if (buffer_[i + 1] != '\n') return Fail(Malformed("boundary line not ended by CRLF"));
        buffer_.erase(0, i + 2);
        if (++part_count_ > options_.max_parts) {
          return Fail(Status::InvalidArgument("too many parts in multipart body (limit " +
                                              std::to_string(options_.max_parts) + ")"));
        }
        state_ = State::kHeaders;
        break;
      }

      case State::kHeaders: {
        std::size_t block_size = 0;
        std::size_t consumed = 0;
        if (buffer_.size() >= 2 && buffer_.compare(0, 2, kCrlf) == 0) {
          // No header lines at all; rejected below for lacking Content-Disposition.
          consumed = 2;
        } else {
          const std::size_t pos = buffer_.find("\r\n\r\n");
          if (pos == std::string::npos) {
            // Up to three bytes of the "\r\n\r\n" that ends a block within the limit may
            // already be here: refuse only what cannot be such a block, or the outcome would
            // depend on where the chunks fall (found by fuzzing).
            if (buffer_.size() > options_.max_header_bytes + 3) {
              return Fail(Malformed("part header block exceeds " +
                                    std::to_string(options_.max_header_bytes) + " bytes"));
            }
            return Status::Ok();
          }
          block_size = pos;
          consumed = pos + 4;
        }
        if (block_size > options_.max_header_bytes) {
          return Fail(Malformed("part header block exceeds " +
                                std::to_string(options_.max_header_bytes) + " bytes"));
        }
        if (Status status = ParseHeaders(std::string_view(buffer_).substr(0, block_size));
            !status.ok()) {
          return Fail(std::move(status));
        }
        buffer_.erase(0, consumed);
        state_ = State::kBody;
        break;
      }

      case State::kBody: {
        const std::size_t pos = buffer_.find(delimiter_);
        if (pos == std::string::npos) {
          // Everything except a possible delimiter prefix at the end is content.
          const std::size_t keep = delimiter_.size() - 1;
          if (buffer_.size() > keep) {
            const std::size_t emit = buffer_.size() - keep;
            if (callbacks_.on_part_data) {
              if (Status status =
                      callbacks_.on_part_data(std::string_view(buffer_).substr(0, emit));
                  !status.ok()) {
                return Fail(std::move(status));
              }
            }
            buffer_.erase(0, emit);
          }
          return Status::Ok();
        }
        if (pos > 0 && callbacks_.on_part_data) {
          if (Status status = callbacks_.on_part_data(std::string_view(buffer_).substr(0, pos));
              !status.ok()) {
            return Fail(std::move(status));
          }
        }
        buffer_.erase(0, pos + delimiter_.size());
        if (callbacks_.on_part_end) {
          if (Status status = callbacks_.on_part_end(); !status.ok())
            return Fail(std::move(status));
        }
        state_ = State::kAfterDelimiter;
        break;
      }

      case State::kEpilogue:
        buffer_.clear();
        return Status::Ok();

      case State::kFailed:
        return error_;
    }
  }
}

Status MultipartParser::ParseHeaders(std::string_view block) {
  MultipartPart part;
  bool has_disposition = false;
  while (!block.empty()) {
    const std::size_t eol = block.find(kCrlf);
    const std::string_view line = block.substr(0, eol);
    block = eol == std::string_view::npos ? std::string_view() : block.substr(eol + 2);
    if (line.empty() || line.front() == ' ' || line.front() == '\t') {
      return Malformed("empty or folded part header line");
    }
    const std::size_t colon = line.find(':');
    if (colon == std::string_view::npos || colon == 0) {
      return Malformed("part header line without a name: '" + std::string(line.substr(0, 80)) +
                       "'");
    }
    const std::string_view name = line.substr(0, colon);
    if (name.find_first_of(" \t") != std::string_view::npos) {
      return Malformed("white space in part header name");
    }
    const std::string_view value = Trim(line.substr(colon + 1));
    part.headers.emplace_back(std::string(name), std::string(value));

    if (EqualsIgnoreCase(name, "Content-Disposition")) {
      Result<HeaderValue> disposition = ParseHeaderValue(value);
      if (!disposition.ok()) return Malformed(disposition.status().message());
      if (disposition->value != "form-data") {
        return Malformed("part Content-Disposition is '" + disposition->value +
                         "', expected form-data");
      }
      std::optional<std::string> field_name = disposition->Param("name");
      if (!field_name) return Malformed("part Content-Disposition without a name");
      part.name = std::move(*field_name);
      part.filename = disposition->Param("filename");
      if (!part.filename) {
        // RFC 5987 extended value: charset'language'percent-encoded.
        if (std::optional<std::string> extended = disposition->Param("filename*")) {
          const std::size_t first = extended->find('\'');
          const std::size_t second =
              first == std::string::npos ? std::string::npos : extended->find('\'', first + 1);
          if (second == std::string::npos) return Malformed("malformed filename* parameter");
          std::optional<std::string> decoded =
              PercentDecode(std::string_view(*extended).substr(second + 1));
          if (!decoded) return Malformed("malformed percent-encoding in filename*");
          part.filename = std::move(*decoded);
        }
      }
      has_disposition = true;
    } else if (EqualsIgnoreCase(name, "Content-Type")) {
      const std::size_t semicolon = value.find(';');
      part.content_type = ToLowerAscii(Trim(value.substr(0, semicolon)));
      if (semicolon != std::string_view::npos) part.content_type += value.substr(semicolon);
    }
  }
  if (!has_disposition) return Malformed("part without a Content-Disposition header");
  if (callbacks_.on_part_begin) return callbacks_.on_part_begin(part);
  return Status::Ok();
}

}  // namespace reconduit::server
