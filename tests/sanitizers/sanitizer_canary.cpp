// A program with one deliberate defect per sanitizer, chosen by its argument. In a
// sanitized build (the asan preset) each must be reported, so a preset whose flags stop
// reaching the compiler, or options that silence a report, fail the tests that run this
// (tests/sanitizers/CMakeLists.txt) instead of letting the suite pass unchecked.
#include <climits>
#include <cstdio>
#include <cstring>
#include <string>

namespace {

// Opaque to the optimizer: the defects below must happen at run time.
volatile int g_index = 8;
volatile int g_big = INT_MAX;

int heap_overflow() {
  char* p = new char[8];
  std::memset(p, 0, 8);
  const int r = p[g_index];  // one past the end
  delete[] p;
  return r;
}

int signed_overflow() {
  int a = g_big;
  a += 1;  // undefined: INT_MAX + 1
  return a == 0;
}

// A volatile pointer: the allocation cannot be elided (as an unused `new` may be).
char* volatile g_block = nullptr;

int leak() {
  g_block = new char[64];
  g_block[0] = static_cast<char>(g_index);
  g_block = nullptr;  // the only pointer to it is gone
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  const std::string what = argc > 1 ? argv[1] : "";
  if (what == "heap") return heap_overflow();
  if (what == "ub") return signed_overflow();
  if (what == "leak") return leak();
  std::fprintf(stderr, "usage: sanitizer_canary heap|ub|leak\n");
  return 2;
}
