// The fuzz targets' entry functions: each takes one input's bytes and runs it through what
// pinsim does with a user's file of that kind, up to (not including) running plugin code.
// libFuzzer drives them (fuzz_main.cpp, the `fuzz` preset); the normal test suite replays the
// seed and regression corpora through the same functions (test_fuzz_corpus.cpp).
#pragma once

#include <string>
#include <string_view>

namespace pinsim::fuzz {

/// How pinsim treated an input.
enum class Outcome {
  accepted,  ///< valid
  refused,   ///< an InputError or LoadError: the input was refused with a located message
  other,     ///< some other exception: refused, but with a message that names no location
};

struct Result {
  Outcome outcome = Outcome::accepted;
  std::string message;  ///< the error's message when refused
};

/// A scene file: parse_json_text, parse_scene (bodies, forces, crosscheck spec), and each
/// force's and the backend's parameters and elements checked against the shipped plugins'
/// tables (no plugin instance is created; "library" references are not loaded).
Result scene(std::string_view bytes);

/// `--set` assignments, one PATH=VALUE per line, applied to configs/pinball.json, then
/// checked as scene() does.
Result set(std::string_view bytes);

/// A bench or stress sweep config (configs/bench, configs/stress): read and checked as
/// `pinsim bench --check` and `pinsim stress --check` do. Relative scene paths resolve
/// against a copy of configs/bench/.
Result sweep_config(std::string_view bytes);

/// A grading rubric (configs/grading): load_rubric. Relative scene paths resolve against a
/// copy of configs/grading/.
Result rubric(std::string_view bytes);

/// The entry function called `name` ("scene", "set", "sweep_config", "rubric"), or null.
using Entry = Result (*)(std::string_view);
Entry entry(std::string_view name);

}  // namespace pinsim::fuzz
