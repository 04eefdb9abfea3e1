// Student "linear_spring" submissions for the grader tests, one per -DSUBMISSION value.
// The physics variants reuse the check-plugin fixtures (tests/fixtures/wrong_spring.hpp);
// one leaves out energy(); the others misbehave the way real submissions do: crash, hang,
// allocate without bound.
#include <cstdint>
#include <cstdlib>
#include <pinsim/plugin.hpp>
#include <vector>

#include "wrong_spring.hpp"

namespace {

#if SUBMISSION >= 10
// Inside the never-mapped first page, but not null: UBSan (the asan preset) checks stores
// through null and would report and exit 1 instead of letting the signal happen.
volatile std::uintptr_t invalid_address = 16;

// Misbehaves before any physics can be checked, so the spring body it wraps does not matter.
template <int Kind>
class Misbehaving : public WrongSpring<Bug::MissingHalf> {
 public:
  using Base = WrongSpring<Bug::MissingHalf>;
  explicit Misbehaving(const pinsim::CreateContext& c) : Base(c) {
    if constexpr (Kind == 12) {
      // Huge allocation, touched so it is real: fails under the grader's memory limit.
      big_.assign(std::size_t{64} << 30, 1);
    }
  }
  static pinsim::PluginInfo info() {
    auto i = Base::info();
    i.name = "linear_spring";
    return i;
  }
  void add_force(const pinsim::StateView& s, pinsim::ForceOut& f) const {
    if constexpr (Kind == 10) {
      // An address the compiler cannot see, so the store really happens.
      *reinterpret_cast<volatile int*>(invalid_address) = 42;  // segmentation fault
    }
    if constexpr (Kind == 11) {
      volatile bool forever = true;
      while (forever) {
      }
    }
    Base::add_force(s, f);
  }

 private:
  std::vector<char> big_;
};
using Submission = Misbehaving<SUBMISSION>;
#elif SUBMISSION == 4
// Right forces and Jacobians (those of the missing-half variant, whose only bug is its
// energy), but no energy() at all: leaving it out must not skip the reference check's
// energy comparison.
class NoEnergy {
 public:
  static pinsim::PluginInfo info() {
    auto i = WrongSpring<Bug::MissingHalf>::info();
    i.name = "linear_spring";
    return i;
  }
  explicit NoEnergy(const pinsim::CreateContext& c) : spring_(c) {}
  void add_force(const pinsim::StateView& s, pinsim::ForceOut& f) const { spring_.add_force(s, f); }
  void add_dfdx(const pinsim::StateView& s, pinsim::Triplets& j) const { spring_.add_dfdx(s, j); }
  void add_dfdv(const pinsim::StateView& s, pinsim::Triplets& j) const { spring_.add_dfdv(s, j); }

 private:
  WrongSpring<Bug::MissingHalf> spring_;
};
using Submission = NoEnergy;
#else
template <Bug B>
class Renamed : public WrongSpring<B> {
 public:
  using WrongSpring<B>::WrongSpring;
  static pinsim::PluginInfo info() {
    auto i = WrongSpring<B>::info();
    i.name = "linear_spring";
    return i;
  }
};
using Submission = Renamed<static_cast<Bug>(SUBMISSION)>;
#endif

}  // namespace

PINSIM_PLUGIN(Submission)
