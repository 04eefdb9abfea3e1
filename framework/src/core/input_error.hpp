// The error types for bad input: anything given to pinsim that it cannot use.
#pragma once

#include <stdexcept>
#include <string>

namespace pinsim {

/// Bad input of any kind: a scene, a rubric, a bench, stress or crosscheck config, a
/// command-line value, a shard (`--shard i/N`), a set of CSVs to merge, a play recording,
/// a run folder. The message names the file (with the JSON path) or the flag, and says what
/// was expected. `pinsim` exits 2 on one: nothing ran.
class InputError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Bad input in a scene file: "<file>: <JSON path>: <what was expected>".
class SceneError : public InputError {
 public:
  using InputError::InputError;
};

}  // namespace pinsim
