// libFuzzer's entry for one target (PINSIM_FUZZ_ENTRY names the function of
// fuzz_entries.hpp). Set PINSIM_FUZZ_STRICT=1 to treat an error message that names no
// file or JSON path (any exception but InputError and LoadError) as a finding too.
#include <spdlog/spdlog.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>

#include "fuzz_entries.hpp"

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  spdlog::set_level(spdlog::level::off);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, std::size_t size) {
  static const bool strict = std::getenv("PINSIM_FUZZ_STRICT") != nullptr;
  const auto r =
      pinsim::fuzz::PINSIM_FUZZ_ENTRY(std::string_view(reinterpret_cast<const char*>(data), size));
  if (strict && r.outcome == pinsim::fuzz::Outcome::other) {
    std::fprintf(stderr, "pinsim fuzz: unlocated error message: %s\n", r.message.c_str());
    std::abort();
  }
  return 0;
}
