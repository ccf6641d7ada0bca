// skintune (internal): how the public API (skintune/skintune.h) turns the
// library's exceptions into error values, so that none crosses the header.
//
// Inside, code throws skintune::internal::Error (base/error.h) with a complete
// message; where the error code matters it throws ApiError, which carries
// one. Each public entry point runs its body through Guarded(), which maps
// ApiError to its code, Error to the entry point's default code, running out
// of memory (std::bad_alloc) and any other exception to kDeviceError.
#pragma once

#include <new>
#include <string>
#include <utility>

#include "base/error.h"
#include "skintune/skintune.h"

namespace skintune::internal {

class ApiError : public Error {
 public:
  ApiError(ErrorCode code, const std::string& message) : Error(message), code_(code) {}
  ErrorCode code() const { return code_; }

 private:
  ErrorCode code_;
};

[[noreturn]] inline void FailWith(ErrorCode code, const std::string& message) { throw ApiError(code, message); }

// Runs `body` (returning T, or void for Status) and returns its value or the
// Status of what it threw; `fallback` is the code of a plain Error.
template <typename T, typename F>
Result<T> GuardedResult(ErrorCode fallback, F&& body) noexcept {
  try {
    return Result<T>(body());
  } catch (const ApiError& e) {
    return Status(e.code(), Bounded(e.what()));
  } catch (const Error& e) {
    return Status(fallback, Bounded(e.what()));
  } catch (const std::bad_alloc&) {
    return Status(ErrorCode::kDeviceError, "out of host memory");
  } catch (const std::exception& e) {
    return Status(ErrorCode::kDeviceError, std::string("internal error: ") + e.what());
  } catch (...) {
    return Status(ErrorCode::kDeviceError, "internal error: unknown exception");
  }
}

template <typename F>
Status Guarded(ErrorCode fallback, F&& body) noexcept {
  Result<bool> r = GuardedResult<bool>(fallback, [&] {
    body();
    return true;
  });
  return r.ok() ? Status() : r.status();
}

}  // namespace skintune::internal
