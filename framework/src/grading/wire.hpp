// The grader's private channel to the sandboxed worker: framed binary messages over one
// socket (file descriptor 3 in the worker), separate from everything the submission prints.
// Frame: u32 magic, u32 code, u64 length, then `length` payload bytes (native byte order:
// both ends are this build on this machine). The grader (trusted) sends requests and parses
// replies strictly: every reply has the exact length its request implies, or a bounded one.
#pragma once

#include <pinsim/abi.h>

#include <cstdint>
#include <cstring>
#include <stdexcept>
#include <string>
#include <vector>

namespace pinsim::grading {

constexpr uint32_t kWireMagic = 0x57475350u;   // "PSGW"
constexpr uint64_t kMaxFrame = 256ull << 20;   // no frame is larger (256 MiB)
constexpr uint32_t kMaxWireString = 1u << 16;  // names, docs, parameter text, messages
constexpr int kChannelFd = 3;                  // the worker's end of the channel

/// Requests (grader -> worker).
enum class Op : uint32_t {
  Open = 1,   ///< str name, u32 kind -> plugin description
  Create,     ///< str params, str scene, state, u32 arity, u64 n, u64 w, u32[w], str ctx -> u64 id
  Destroy,    ///< u64 id -> ()
  AddForce,   ///< u64 id, state, f64[2n] f -> f64[2n] f
  Energy,     ///< u64 id, state -> f64
  Jacobians,  ///< u64 id, state, u32 want_dfdx, u32 want_dfdv -> u64 k, k x (u32 which, row, col,
              ///< pad, f64)
  Advance,    ///< u64 id, state, f64 dt -> f64[2n] x, f64[2n] v, u64 k, k x event
  Distance,   ///< u64 id, f64 x, f64 y, f64 t -> f64 d, i64 obstacle
  Quit,       ///< -> ()
};

/// Reply codes (worker -> grader).
enum class Reply : uint32_t { Ok = 0, PluginError = 1 };

/// A malformed message: the peer broke the protocol.
class WireError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

class WireWriter {
 public:
  void u32(uint32_t v) { raw(&v, sizeof v); }
  void u64(uint64_t v) { raw(&v, sizeof v); }
  void i64(int64_t v) { raw(&v, sizeof v); }
  void f64(double v) { raw(&v, sizeof v); }
  void f64s(const double* p, std::size_t n) { raw(p, n * sizeof(double)); }
  void str(const std::string& s) {
    u32(static_cast<uint32_t>(s.size()));
    raw(s.data(), s.size());
  }
  void raw(const void* p, std::size_t n) { buf_.append(static_cast<const char*>(p), n); }
  /// The state as u64 n, f64 t, x[2n], v[2n], inv_mass[n], radius[n].
  void state(const pinsim_state_view& s);
  const std::string& bytes() const { return buf_; }
  std::string& bytes() { return buf_; }

 private:
  std::string buf_;
};

/// Reads a payload; every read checks the remaining length and throws WireError.
class WireReader {
 public:
  explicit WireReader(const std::string& b) : p_(b.data()), end_(b.data() + b.size()) {}
  uint32_t u32() { return pod<uint32_t>(); }
  uint64_t u64() { return pod<uint64_t>(); }
  int64_t i64() { return pod<int64_t>(); }
  double f64() { return pod<double>(); }
  void f64s(double* out, std::size_t n) { raw(out, n * sizeof(double)); }
  std::string str(uint32_t max = kMaxWireString);
  void raw(void* out, std::size_t n) {
    need(n);
    if (n == 0) return;  // an empty vector's data() may be null: memcpy's pointers must not be
    std::memcpy(out, p_, n);
    p_ += n;
  }
  /// Bytes not read yet.
  std::size_t left() const { return static_cast<std::size_t>(end_ - p_); }
  void need(std::size_t n) const {
    if (left() < n) throw WireError("message too short");
  }
  /// Throws unless every byte was read.
  void finish() const {
    if (left() != 0) throw WireError("message has " + std::to_string(left()) + " extra bytes");
  }

 private:
  template <class T>
  T pod() {
    T v;
    raw(&v, sizeof v);
    return v;
  }
  const char* p_;
  const char* end_;
};

/// A state read off the wire, owning its arrays.
struct WireState {
  uint64_t n = 0;
  double t = 0.0;
  std::vector<double> x, v, inv_mass, radius;
  /// Reads one; `max_n` bounds the particle count before anything is allocated.
  void read(WireReader& r, uint64_t max_n);
  pinsim_state_view view() const {
    return {n, t, x.data(), v.data(), inv_mass.data(), radius.data()};
  }
};

/// Blocking whole-frame I/O, for the worker's side. Return false on end of file or error.
bool write_frame(int fd, uint32_t code, const std::string& payload);
bool read_frame(int fd, uint32_t& code, std::string& payload, uint64_t max = kMaxFrame);

}  // namespace pinsim::grading
