// The one error type for bad scenes and bad command-line values.
#pragma once

#include <stdexcept>
#include <string>

namespace pinsim {

/// A bad scene: the message names the file, the JSON path and what was expected.
class SceneError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

}  // namespace pinsim
