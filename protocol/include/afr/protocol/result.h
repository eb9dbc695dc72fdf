// The values that the codec and the transport return instead of throwing on bad input: a
// Status (ok, or an error message naming the message, the field and the problem) and a
// Result<T> (a value, or such a message). Successful paths allocate nothing.
#pragma once

#include <afr/common/check.h>

#include <optional>
#include <string>
#include <utility>

namespace afr::protocol {

class [[nodiscard]] Status {
 public:
  Status() = default;  // ok
  static Status error(std::string message) {
    Status s;
    s.message_ = message.empty() ? std::string("unspecified error") : std::move(message);
    return s;
  }

  bool ok() const { return message_.empty(); }
  explicit operator bool() const { return ok(); }
  // Empty when ok; otherwise "<message>.<field>: <problem>", suitable for a log line.
  const std::string& message() const { return message_; }

 private:
  std::string message_;
};

template <class T>
class [[nodiscard]] Result {
 public:
  Result(T value) : value_(std::move(value)) {}  // NOLINT: implicit by design, like expected
  Result(Status status) : status_(std::move(status)) { AFR_CHECK(!status_.ok()); }

  bool ok() const { return value_.has_value(); }
  explicit operator bool() const { return ok(); }
  const Status& status() const { return status_; }
  const std::string& error() const { return status_.message(); }

  // Only when ok().
  T& value() & {
    AFR_CHECK(ok());
    return *value_;
  }
  const T& value() const& {
    AFR_CHECK(ok());
    return *value_;
  }
  T&& value() && {
    AFR_CHECK(ok());
    return std::move(*value_);
  }
  T* operator->() { return &value(); }
  const T* operator->() const { return &value(); }
  T& operator*() & { return value(); }
  const T& operator*() const& { return value(); }

 private:
  std::optional<T> value_;
  Status status_;
};

}  // namespace afr::protocol
