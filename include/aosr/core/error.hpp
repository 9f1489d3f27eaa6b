// Error types thrown at aosr's boundaries (files, configs, CLI, public entry points).
//
// Rules for the whole library:
//  * Public functions validate their arguments before doing any work, and before handing
//    anything to Ceres (which aborts on misuse) or FFTW (which does not check).
//  * InvalidArgument names the function, the argument, the value received and what is allowed.
//  * IoError names the path and the underlying library's message.
//  * A request that would need more memory than the limit (memory.hpp) is refused before allocating, with
//    ResourceError saying how much it would need.
//  * Non-convergence of an iterative solver is *not* an exception: it is reported in the
//    solver's Summary. NumericalError is reserved for a NaN/Inf that would otherwise leak.
#pragma once

#include <sstream>
#include <stdexcept>
#include <string>

namespace aosr {

class Error : public std::runtime_error {
 public:
  explicit Error(const std::string& what) : std::runtime_error(what) {}
};

class InvalidArgument : public Error {
 public:
  // Message: "<function>: invalid <argument> = <value>; allowed: <allowed>".
  InvalidArgument(const std::string& function, const std::string& argument,
                  const std::string& value, const std::string& allowed);
  explicit InvalidArgument(const std::string& message) : Error(message) {}
};

class IoError : public Error {
 public:
  // Message: "<path>: <message>".
  IoError(const std::string& path, const std::string& message);
  const std::string& path() const { return path_; }

 private:
  std::string path_;
};

// A request (sizes from a file, config or argument) that needs more memory than the limit of memory.hpp.
class ResourceError : public Error {
 public:
  explicit ResourceError(const std::string& what) : Error(what) {}
};

class NumericalError : public Error {
 public:
  explicit NumericalError(const std::string& what) : Error(what) {}
};

// Formats any streamable value for an error message.
template <typename T>
std::string ToString(const T& value) {
  std::ostringstream os;
  os.precision(10);
  os << value;
  return os.str();
}

// Sets *why (when `why` is not null) to `msg` and returns false: the exit of an Options::IsValid(why) that names
// its bad field.
inline bool Fail(std::string* why, const std::string& msg) {
  if (why != nullptr) *why = msg;
  return false;
}

// Throws InvalidArgument(function, argument, ToString(value), allowed) unless `ok`.
template <typename T>
void CheckArgument(bool ok, const std::string& function, const std::string& argument, const T& value,
                   const std::string& allowed) {
  if (!ok) throw InvalidArgument(function, argument, ToString(value), allowed);
}

}  // namespace aosr
