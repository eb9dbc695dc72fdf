// The error afr throws at its boundaries (files, flags, network): the message names the input
// and what is wrong with it, so it can be shown to a user as it is.
#pragma once

#include <stdexcept>
#include <string>

namespace afr {

class Error : public std::runtime_error {
 public:
  explicit Error(const std::string& message) : std::runtime_error(message) {}
};

}  // namespace afr
