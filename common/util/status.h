// Status and StatusOr: how the library reports errors on input from robots and files.
// Internal invariants use glog's CHECK instead; nothing a client sends may abort the process.
#pragma once

#include <optional>
#include <string>
#include <utility>

#include <glog/logging.h>

namespace placerec {

enum class StatusCode {
  kOk = 0,
  kInvalidArgument,  // a bad option value or a malformed request
  kBadImage,         // bytes that do not decode to an image of the stated kind and size
  kNotFound,
  kIoError,     // a file or database that cannot be read or written
  kOverloaded,  // the server's queue is full
  kInternal,
};

const char* StatusCodeName(StatusCode code);

class Status {
 public:
  Status() = default;
  Status(StatusCode code, std::string message) : code_(code), message_(std::move(message)) {}

  static Status Ok() { return Status(); }
  static Status InvalidArgument(std::string m) {
    return {StatusCode::kInvalidArgument, std::move(m)};
  }
  static Status BadImage(std::string m) { return {StatusCode::kBadImage, std::move(m)}; }
  static Status NotFound(std::string m) { return {StatusCode::kNotFound, std::move(m)}; }
  static Status IoError(std::string m) { return {StatusCode::kIoError, std::move(m)}; }
  static Status Overloaded(std::string m) { return {StatusCode::kOverloaded, std::move(m)}; }
  static Status Internal(std::string m) { return {StatusCode::kInternal, std::move(m)}; }

  bool ok() const { return code_ == StatusCode::kOk; }
  StatusCode code() const { return code_; }
  const std::string& message() const { return message_; }
  // "bad image: width 0" style text for logs and CLI errors.
  std::string ToString() const;

 private:
  StatusCode code_ = StatusCode::kOk;
  std::string message_;
};

// A value or the error that prevented computing it.
template <typename T>
class StatusOr {
 public:
  StatusOr(Status status) : status_(std::move(status)) {  // NOLINT: implicit by design
    CHECK(!status_.ok()) << "StatusOr built from an ok Status without a value";
  }
  StatusOr(T value) : value_(std::move(value)) {}  // NOLINT: implicit by design

  bool ok() const { return status_.ok(); }
  const Status& status() const { return status_; }
  const T& value() const& {
    CHECK(ok()) << status_.ToString();
    return *value_;
  }
  T& value() & {
    CHECK(ok()) << status_.ToString();
    return *value_;
  }
  T&& value() && {
    CHECK(ok()) << status_.ToString();
    return std::move(*value_);
  }
  const T* operator->() const { return &value(); }
  T* operator->() { return &value(); }
  const T& operator*() const& { return value(); }
  T& operator*() & { return value(); }

 private:
  Status status_;
  std::optional<T> value_;
};

}  // namespace placerec

// Returns early from the calling function when `expr` yields a non-ok Status.
#define PLACEREC_RETURN_IF_ERROR(expr)                   \
  do {                                                   \
    ::placerec::Status placerec_status_ = (expr);        \
    if (!placerec_status_.ok()) return placerec_status_; \
  } while (0)
