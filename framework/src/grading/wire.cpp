#include "grading/wire.hpp"

#include <errno.h>
#include <sys/socket.h>
#include <unistd.h>

namespace pinsim::grading {
namespace {

bool write_all(int fd, const char* p, std::size_t n) {
  while (n > 0) {
    const ssize_t w = ::send(fd, p, n, MSG_NOSIGNAL);
    if (w < 0 && errno == EINTR) continue;
    if (w <= 0) return false;
    p += w;
    n -= static_cast<std::size_t>(w);
  }
  return true;
}

bool read_all(int fd, char* p, std::size_t n) {
  while (n > 0) {
    const ssize_t r = ::read(fd, p, n);
    if (r < 0 && errno == EINTR) continue;
    if (r <= 0) return false;
    p += r;
    n -= static_cast<std::size_t>(r);
  }
  return true;
}

}  // namespace

void WireWriter::state(const pinsim_state_view& s) {
  u64(s.n);
  f64(s.t);
  f64s(s.x, 2 * s.n);
  f64s(s.v, 2 * s.n);
  f64s(s.inv_mass, s.n);
  f64s(s.radius, s.n);
}

std::string WireReader::str(uint32_t max) {
  const uint32_t n = u32();
  if (n > max)
    throw WireError("string of " + std::to_string(n) + " bytes (limit " + std::to_string(max) +
                    ")");
  need(n);
  std::string s(p_, n);
  p_ += n;
  return s;
}

void WireState::read(WireReader& r, uint64_t max_n) {
  n = r.u64();
  if (n > max_n) throw WireError("state of " + std::to_string(n) + " particles");
  t = r.f64();
  r.need(6 * n * sizeof(double));
  x.resize(2 * n);
  v.resize(2 * n);
  inv_mass.resize(n);
  radius.resize(n);
  r.f64s(x.data(), 2 * n);
  r.f64s(v.data(), 2 * n);
  r.f64s(inv_mass.data(), n);
  r.f64s(radius.data(), n);
}

bool write_frame(int fd, uint32_t code, const std::string& payload) {
  char head[16];
  const uint32_t magic = kWireMagic;
  const uint64_t len = payload.size();
  std::memcpy(head, &magic, 4);
  std::memcpy(head + 4, &code, 4);
  std::memcpy(head + 8, &len, 8);
  return write_all(fd, head, sizeof head) && write_all(fd, payload.data(), payload.size());
}

bool read_frame(int fd, uint32_t& code, std::string& payload, uint64_t max) {
  char head[16];
  if (!read_all(fd, head, sizeof head)) return false;
  uint32_t magic;
  uint64_t len;
  std::memcpy(&magic, head, 4);
  std::memcpy(&code, head + 4, 4);
  std::memcpy(&len, head + 8, 8);
  if (magic != kWireMagic || len > max) return false;
  payload.resize(len);
  return read_all(fd, payload.data(), len);
}

}  // namespace pinsim::grading
