#include "aosr/core/error.hpp"

namespace aosr {

InvalidArgument::InvalidArgument(const std::string& function, const std::string& argument,
                                 const std::string& value, const std::string& allowed)
    : Error(function + ": invalid " + argument + " = " + value + "; allowed: " + allowed) {}

IoError::IoError(const std::string& path, const std::string& message)
    : Error(path + ": " + message), path_(path) {}

}  // namespace aosr
