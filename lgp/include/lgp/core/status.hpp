// Recoverable failures are returned, not thrown: Status carries a message that names the
// offending field, file, row or column. Exceptions are used only at the frontends boundary.
#pragma once

#include <cassert>
#include <optional>
#include <string>
#include <utility>
#include <variant>

#ifdef NDEBUG
#define LGP_ASSERT(cond) ((void)0)
#else
#define LGP_ASSERT(cond) assert(cond)
#endif

namespace lgp {

// [[nodiscard]]: a Status or Expected that nobody reads is a failure nobody sees.
class [[nodiscard]] Status {
 public:
  Status() = default;
  static Status ok() { return Status(); }
  static Status error(std::string msg) {
    Status s;
    s.msg_ = std::move(msg);
    return s;
  }
  bool isOk() const { return !msg_.has_value(); }
  explicit operator bool() const { return isOk(); }
  const std::string& message() const {
    static const std::string kEmpty;
    return msg_ ? *msg_ : kEmpty;
  }

 private:
  std::optional<std::string> msg_;
};

// A value or an error message.
template <class T>
class [[nodiscard]] Expected {
 public:
  Expected(T v) : v_(std::move(v)) {}
  Expected(Status s) : v_(std::move(s)) { LGP_ASSERT(!std::get<Status>(v_).isOk()); }
  bool hasValue() const { return std::holds_alternative<T>(v_); }
  explicit operator bool() const { return hasValue(); }
  T& value() { return std::get<T>(v_); }
  const T& value() const { return std::get<T>(v_); }
  T& operator*() { return value(); }
  const T& operator*() const { return value(); }
  T* operator->() { return &value(); }
  const T* operator->() const { return &value(); }
  const std::string& error() const { return std::get<Status>(v_).message(); }
  Status status() const { return hasValue() ? Status::ok() : std::get<Status>(v_); }

 private:
  std::variant<T, Status> v_;
};

}  // namespace lgp
