// Fuzz entries for sweep configs and grading rubrics. Both are read from files whose
// relative scene paths matter, so each input is written into a private copy of configs/
// (symbolic links to the shipped files) and read from there.
#include <unistd.h>

#include <cstdlib>
#include <fstream>
#include <string>

#include "fuzz_guard.hpp"
#include "grading/rubric.hpp"
#include "tools/bench.hpp"
#include "tools/stress.hpp"

namespace pinsim::fuzz {
namespace {

namespace fs = std::filesystem;

/// A per-process copy of configs/ made of links, removed at exit.
const fs::path& mirror() {
  static const fs::path dir = [] {
    const fs::path d = fs::temp_directory_path() / ("pinsim-fuzz-" + std::to_string(::getpid()));
    fs::remove_all(d);
    fs::create_directories(d);
    for (const auto& e : fs::recursive_directory_iterator(configs_dir())) {
      const fs::path to = d / fs::relative(e.path(), configs_dir());
      if (e.is_directory())
        fs::create_directories(to);
      else
        fs::create_symlink(e.path(), to);
    }
    std::atexit([] { fs::remove_all(mirror()); });
    return d;
  }();
  return dir;
}

/// Writes the input as `sub`/fuzz_input.json in the mirror; returns its path.
fs::path input_file(const char* sub, std::string_view bytes) {
  const fs::path f = mirror() / sub / "fuzz_input.json";
  std::ofstream(f, std::ios::binary | std::ios::trunc)
      .write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  return f;
}

}  // namespace

Result sweep_config(std::string_view bytes) {
  const fs::path f = input_file("bench", bytes);
  const Result b = guarded([&] {
    bench::Options o;
    o.config = f;
    o.check_only = true;
    bench::run(o);
  });
  const Result s = guarded([&] {
    stress::Options o;
    o.config = f;
    o.check_only = true;
    stress::run(o);
  });
  // The worse of the two: an unlocated message, else valid for either tool.
  if (b.outcome == Outcome::other) return b;
  if (s.outcome == Outcome::other) return s;
  return b.outcome == Outcome::accepted ? b : s;
}

Result rubric(std::string_view bytes) {
  const fs::path f = input_file("grading", bytes);
  return guarded([&] { (void)load_rubric(f); });
}

}  // namespace pinsim::fuzz
