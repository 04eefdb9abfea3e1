// What the fuzz entry functions share: classifying how an input was refused, and where the
// shipped configs are.
#pragma once

#include <exception>
#include <filesystem>

#include "core/input_error.hpp"
#include "core/plugin_loader.hpp"
#include "fuzz_entries.hpp"

namespace pinsim::fuzz {

/// Runs `f`; an exception is a refusal, located (InputError, LoadError) or not (any other).
/// Anything worse (a signal, a sanitizer report, a non-std exception) is left to the fuzzer.
template <class F>
Result guarded(F&& f) {
  try {
    f();
    return {};
  } catch (const InputError& e) {
    return {Outcome::refused, e.what()};
  } catch (const LoadError& e) {
    return {Outcome::refused, e.what()};
  } catch (const std::exception& e) {
    return {Outcome::other, e.what()};
  }
}

/// The source tree's configs/ folder.
inline std::filesystem::path configs_dir() {
  return std::filesystem::path(PINSIM_SOURCE_DIR) / "configs";
}

}  // namespace pinsim::fuzz
