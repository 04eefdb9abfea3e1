// "linear_spring" submissions whose plugin table disagrees with itself, one per
// -DINCONSISTENT value: the grader and check-plugin must call nothing through a pointer the
// flags promise but the table lacks, and say what is wrong.
//   1: declares PINSIM_CAP_ENERGY (by hand, in info()) but has no energy().
//   2: a correct table, but the library forges the worker's description of it on the
//      grader's channel (descriptor 3) when it loads: ENERGY declared, no energy() sent.
//   3: correct physics, but forgets PINSIM_CAP_INTERNAL (a plain flag, not a function).
#include <unistd.h>

#include <cstdint>
#include <string>

#include "correct_source/student_spring.hpp"

namespace {

#if INCONSISTENT == 2
void put(std::string& s, const void* p, std::size_t n) { s.append(static_cast<const char*>(p), n); }
void put_u32(std::string& s, uint32_t v) { put(s, &v, 4); }
void put_str(std::string& s, const std::string& v) {
  put_u32(s, static_cast<uint32_t>(v.size()));
  s += v;
}

// The grader's Open reply (grading/wire.hpp), written before the worker writes the true one.
[[maybe_unused]] __attribute__((constructor)) void forge_description() {
  std::string body;
  put_u32(body, PINSIM_KIND_FORCE);
  put_u32(body, 2);  // arity
  put_u32(body, PINSIM_CAP_ENERGY | PINSIM_CAP_INTERNAL);
  put_u32(body, 0);  // has energy(): no
  put_u32(body, 0);  // has add_jacobians(): no
  put_u32(body, 0);  // has distance(): no
  put_str(body, "linear_spring");
  put_str(body, "1.0");
  put_str(body, "forged");
  put_str(body, "libstudent_spring.so");
  put_u32(body, 0);  // no parameters
  std::string frame;
  put_u32(frame, 0x57475350u);  // magic
  put_u32(frame, 0);            // Reply::Ok
  const uint64_t len = body.size();
  put(frame, &len, 8);
  frame += body;
  [[maybe_unused]] const auto w = ::write(3, frame.data(), frame.size());
}
#endif

class Submission {
 public:
  static pinsim::PluginInfo info() {
    pinsim::PluginInfo i = StudentSpring::info();
#if INCONSISTENT == 1
    i.capabilities |= PINSIM_CAP_ENERGY;  // promised, never written
#elif INCONSISTENT == 3
    i.capabilities = 0;  // the spring is internal, but does not say so
#endif
    return i;
  }
  explicit Submission(const pinsim::CreateContext& c) : spring_(c) {}
  void add_force(const pinsim::StateView& s, pinsim::ForceOut& f) const { spring_.add_force(s, f); }
#if INCONSISTENT != 1
  double energy(const pinsim::StateView& s) const { return spring_.energy(s); }
#endif
  void add_dfdx(const pinsim::StateView& s, pinsim::Triplets& j) const { spring_.add_dfdx(s, j); }

 private:
  StudentSpring spring_;
};

}  // namespace

PINSIM_PLUGIN(Submission)
