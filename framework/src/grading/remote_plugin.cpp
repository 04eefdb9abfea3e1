#include "grading/remote_plugin.hpp"

#include <errno.h>
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <deque>
#include <nlohmann/json.hpp>
#include <vector>

#include "core/clock.hpp"
#include "core/format.hpp"
#include "core/plugin_table_check.hpp"

namespace pinsim::grading {
namespace {

/// The worker whose tables are live. The C table's create() has no context pointer, so the
/// proxy's create finds its worker here; the grader runs one test (one worker) at a time.
RemoteWorker* g_active = nullptr;

constexpr uint64_t kSmallReply = kMaxWireString + 8;  // error messages fit in this
constexpr uint64_t kEventBytes = 10 * 8;
constexpr uint64_t kMaxEventsPerParticle = 4096;

struct Instance {
  RemoteWorker* worker;
  uint64_t id;
  uint64_t n;         ///< particles at create (replies are sized by the request's state)
  int64_t obstacles;  ///< obstacles in the scene (backends), for checking event indices
};

void set_error(pinsim_error* err, const std::string& msg) {
  if (err == nullptr || err->message == nullptr || err->capacity == 0) return;
  const std::size_t n = std::min<std::size_t>(msg.size(), err->capacity - 1);
  std::memcpy(err->message, msg.data(), n);
  err->message[n] = '\0';
}

/// Runs one forwarded call; exceptions become the ABI's error code and message.
template <class F>
int guarded(pinsim_error* err, F&& f) {
  try {
    f();
    return 0;
  } catch (const std::exception& e) {
    set_error(err, e.what());
    return 1;
  }
}

void* r_create(const pinsim_create_args* a, pinsim_error* err) {
  RemoteWorker* w = g_active;
  if (w == nullptr) {
    set_error(err, "the submission's worker has ended");
    return nullptr;
  }
  try {
    WireWriter out;
    out.str(a->params_json ? a->params_json : "{}");
    out.str(a->scene_json ? a->scene_json : "");
    out.state(*a->initial);
    // Index words: n x arity, or for whole-body elements (PINSIM_ARITY_VARIABLE) each
    // element's length followed by its indices.
    uint64_t words = a->n_elements * a->arity;
    if (a->arity == PINSIM_ARITY_VARIABLE) {
      words = 0;
      for (uint64_t e = 0; e < a->n_elements; ++e) words += 1 + a->elements[words];
    }
    out.u32(a->arity);
    out.u64(a->n_elements);
    out.u64(words);
    out.raw(a->elements, words * sizeof(uint32_t));
    out.str(a->context ? a->context : "");
    int64_t obstacles = 0;
    if (a->scene_json != nullptr) {
      const auto scene = nlohmann::json::parse(a->scene_json, nullptr, false);
      if (scene.is_object() && scene.contains("obstacles") && scene["obstacles"].is_array())
        obstacles = static_cast<int64_t>(scene["obstacles"].size());
    }
    const std::string reply = w->call(Op::Create, out.bytes(), kSmallReply);
    WireReader in(reply);
    const uint64_t id = in.u64();
    in.finish();
    return new Instance{w, id, a->initial->n, obstacles};
  } catch (const std::exception& e) {
    set_error(err, e.what());
    return nullptr;
  }
}

void r_destroy(void* self) {
  auto* inst = static_cast<Instance*>(self);
  if (g_active == inst->worker && inst->worker->fault() == WorkerFault::None) {
    try {
      WireWriter out;
      out.u64(inst->id);
      inst->worker->call(Op::Destroy, out.bytes(), kSmallReply);
    } catch (const std::exception&) {
      // Nothing to report: the worker is torn down at the end of the test anyway.
    }
  }
  delete inst;
}

Instance& live(void* self) {
  auto* inst = static_cast<Instance*>(self);
  if (g_active != inst->worker) throw WorkerGone("the submission's worker has ended");
  return *inst;
}

int r_add_force(void* self, const pinsim_state_view* s, double* f, pinsim_error* err) {
  return guarded(err, [&] {
    Instance& inst = live(self);
    WireWriter out;
    out.u64(inst.id);
    out.state(*s);
    out.f64s(f, 2 * s->n);
    const std::string reply = inst.worker->call(Op::AddForce, out.bytes(), 16 * s->n);
    WireReader in(reply);
    in.f64s(f, 2 * s->n);
    in.finish();
  });
}

int r_energy(void* self, const pinsim_state_view* s, double* e, pinsim_error* err) {
  return guarded(err, [&] {
    Instance& inst = live(self);
    WireWriter out;
    out.u64(inst.id);
    out.state(*s);
    const std::string reply = inst.worker->call(Op::Energy, out.bytes(), 8);
    WireReader in(reply);
    *e = in.f64();
    in.finish();
  });
}

int r_add_jacobians(void* self, const pinsim_state_view* s, const pinsim_triplet_sink* dfdx,
                    const pinsim_triplet_sink* dfdv, pinsim_error* err) {
  return guarded(err, [&] {
    Instance& inst = live(self);
    WireWriter out;
    out.u64(inst.id);
    out.state(*s);
    out.u32(dfdx != nullptr);
    out.u32(dfdv != nullptr);
    const std::string reply = inst.worker->call(Op::Jacobians, out.bytes(), kMaxFrame);
    WireReader in(reply);
    const uint64_t count = in.u64();
    if (count > in.left() / 24 || count * 24 != in.left())
      throw WireError("Jacobian reply of the wrong size");
    const uint64_t dofs = 2 * s->n;
    for (uint64_t k = 0; k < count; ++k) {
      const uint32_t which = in.u32(), row = in.u32(), col = in.u32();
      in.u32();
      const double value = in.f64();
      const pinsim_triplet_sink* sink = which == 0 ? dfdx : which == 1 ? dfdv : nullptr;
      if (sink == nullptr || row >= dofs || col >= dofs)
        throw PluginCallError("add_jacobians reported an entry (" + std::to_string(row) + ", " +
                              std::to_string(col) + ") outside the " + std::to_string(dofs) +
                              " x " + std::to_string(dofs) + " matrix it was asked for");
      sink->add(sink->context, row, col, value);
    }
  });
}

int r_advance(void* self, pinsim_state_mut* s, double dt, const pinsim_event_sink* events,
              pinsim_error* err) {
  return guarded(err, [&] {
    Instance& inst = live(self);
    WireWriter out;
    out.u64(inst.id);
    const pinsim_state_view v{s->n, s->t, s->x, s->v, s->inv_mass, s->radius};
    out.state(v);
    out.f64(dt);
    const uint64_t max = 32 * s->n + 8 + kEventBytes * kMaxEventsPerParticle * (s->n + 1);
    const std::string reply = inst.worker->call(Op::Advance, out.bytes(), max);
    WireReader in(reply);
    std::vector<double> x(2 * s->n), vel(2 * s->n);
    in.f64s(x.data(), x.size());
    in.f64s(vel.data(), vel.size());
    const uint64_t count = in.u64();
    if (count > in.left() / kEventBytes || count * kEventBytes != in.left())
      throw WireError("advance reply of the wrong size");
    std::vector<pinsim_event> evs(count);
    const auto n = static_cast<int64_t>(s->n);
    for (auto& e : evs) {
      e.t = in.f64();
      e.particle = in.i64();
      e.obstacle = in.i64();
      e.other = in.i64();
      in.f64s(e.point, 2);
      in.f64s(e.normal, 2);
      e.vn_before = in.f64();
      e.vn_after = in.f64();
      if (e.particle < 0 || e.particle >= n || e.other < -1 || e.other >= n || e.obstacle < -1 ||
          e.obstacle >= inst.obstacles)
        throw PluginCallError("advance reported a contact of particle " +
                              std::to_string(e.particle) + " with obstacle " +
                              std::to_string(e.obstacle) + " / particle " +
                              std::to_string(e.other) + ", which do not exist");
    }
    std::copy(x.begin(), x.end(), s->x);
    std::copy(vel.begin(), vel.end(), s->v);
    if (events != nullptr)
      for (const auto& e : evs) events->emit(events->context, &e);
  });
}

int r_distance(void* self, const double* p, double t, double* d, int64_t* obstacle,
               pinsim_error* err) {
  return guarded(err, [&] {
    Instance& inst = live(self);
    WireWriter out;
    out.u64(inst.id);
    out.f64s(p, 2);
    out.f64(t);
    const std::string reply = inst.worker->call(Op::Distance, out.bytes(), 16);
    WireReader in(reply);
    *d = in.f64();
    const int64_t o = in.i64();
    in.finish();
    if (o < -1 || o >= inst.obstacles)
      throw PluginCallError("distance reported obstacle " + std::to_string(o) +
                            ", which does not exist");
    if (obstacle != nullptr) *obstacle = o;
  });
}

}  // namespace

/// The proxy table and the strings it points into.
struct RemoteWorker::Table {
  pinsim_plugin table{};
  std::vector<pinsim_param> params;
  std::deque<std::string> strings;
  const char* keep(std::string s) {
    strings.push_back(std::move(s));
    return strings.back().c_str();
  }
};

const char* op_name(Op op) {
  switch (op) {
    case Op::Open:
      return "loading the library";
    case Op::Create:
      return "create";
    case Op::Destroy:
      return "destroy";
    case Op::AddForce:
      return "add_force";
    case Op::Energy:
      return "energy";
    case Op::Jacobians:
      return "add_jacobians";
    case Op::Advance:
      return "advance";
    case Op::Distance:
      return "distance";
    case Op::Quit:
      return "quit";
  }
  return "?";
}

RemoteWorker::RemoteWorker(Sandboxed process, SandboxLimits limits, double deadline,
                           std::size_t output_limit)
    : proc_(process),
      limits_(limits),
      deadline_(deadline),
      output_limit_(output_limit),
      printed_(output_limit, 0) {
  ::fcntl(proc_.channel_fd, F_SETFL, O_NONBLOCK);
}

void RemoteWorker::begin_test(double deadline) {
  deadline_ = deadline;
  drain_output();
  printed_ = BoundedText(output_limit_, 0);
  if (fault_ == WorkerFault::None) g_active = this;
}

std::string RemoteWorker::end_test() {
  drain_output();
  if (g_active == this) g_active = nullptr;
  last_printed_bytes_ = printed_.total();
  std::string text = printed_.total() > 0 ? printed_.text() : std::string();
  printed_ = BoundedText(output_limit_, 0);
  return text;
}

RemoteWorker::~RemoteWorker() {
  if (g_active == this) g_active = nullptr;
  if (proc_.pid > 0 || proc_.fallback) kill_and_reap(proc_, false);
}

void RemoteWorker::drain_output() {
  if (proc_.output_fd < 0) return;
  char buf[65536];
  for (;;) {
    const ssize_t n = ::read(proc_.output_fd, buf, sizeof buf);
    if (n > 0) {
      printed_.append(buf, static_cast<std::size_t>(n));
      continue;
    }
    if (n == 0) {
      ::close(proc_.output_fd);
      proc_.output_fd = -1;
    }
    return;
  }
}

void RemoteWorker::fail(WorkerFault fault, const std::string& why, Op op) {
  if (fault_ != WorkerFault::None) return;
  fault_ = fault;
  failed_op_ = op_name(op);
  if (g_active == this) g_active = nullptr;
  // Let a dying worker finish dying, so its exit status says how; then end the sandbox.
  StepEnd end;
  if (fault == WorkerFault::Died) {
    int status = 0;
    pid_t w = 0;
    for (int i = 0; i < 200 && w == 0; ++i) {
      w = ::waitpid(proc_.pid, &status, WNOHANG);
      if (w == 0) ::usleep(5000);
    }
    if (w == proc_.pid) {
      end.exited = WIFEXITED(status);
      end.exit_code = end.exited ? WEXITSTATUS(status) : -1;
      end.signal = WIFSIGNALED(status) ? WTERMSIG(status) : 0;
      proc_.pid = -1;
    }
  }
  drain_output();
  Sandboxed rest = proc_;
  proc_.output_fd = -1;
  const StepEnd killed = kill_and_reap(rest, fault == WorkerFault::TimedOut);
  proc_.pid = -1;
  proc_.channel_fd = -1;
  proc_.fallback = false;  // swept with `rest`
  proc_.tmp.clear();
  if (fault == WorkerFault::Died) {
    if (!end.exited && end.signal == 0) end = killed;
    const std::string how = end.failure(limits_);
    failure_ = how.empty() ? "exited (status 0) in the middle of the test, during " + failed_op_
                           : how + ", during " + failed_op_;
  } else if (fault == WorkerFault::TimedOut) {
    failure_ = "did not finish within the wall-clock limit of " + num(limits_.wall_seconds) +
               " s (an infinite loop, a deadlock " + "or a sleep?), during " + failed_op_ +
               ", and was killed";
  } else {
    failure_ = why + ", during " + failed_op_;
  }
}

std::string RemoteWorker::call(Op op, const std::string& payload, uint64_t max_reply) {
  if (fault_ != WorkerFault::None) throw WorkerGone(failure_);
  // The whole frame goes out while replies and printing are read, so neither side blocks.
  std::string frame(16, '\0');
  const uint32_t magic = kWireMagic, code = static_cast<uint32_t>(op);
  const uint64_t len = payload.size();
  std::memcpy(frame.data(), &magic, 4);
  std::memcpy(frame.data() + 4, &code, 4);
  std::memcpy(frame.data() + 8, &len, 8);
  frame += payload;
  std::size_t sent = 0;
  std::string head, body;
  uint32_t reply_code = 0;
  uint64_t reply_len = 0;
  bool have_head = false;
  const uint64_t limit = std::max(max_reply, kSmallReply);
  for (;;) {
    const double left = deadline_ - steady_seconds();
    if (left <= 0) {
      fail(WorkerFault::TimedOut, "", op);
      throw WorkerGone(failure_);
    }
    pollfd p[2] = {
        {proc_.channel_fd, static_cast<short>(POLLIN | (sent < frame.size() ? POLLOUT : 0)), 0},
        {proc_.output_fd, POLLIN, 0}};
    const int np = proc_.output_fd >= 0 ? 2 : 1;
    const int r = ::poll(p, np, static_cast<int>(std::min(left, 0.25) * 1000) + 1);
    if (r < 0 && errno != EINTR) {
      fail(WorkerFault::Died, "poll failed", op);
      throw WorkerGone(failure_);
    }
    if (np == 2 && (p[1].revents & (POLLIN | POLLHUP))) drain_output();
    if (sent < frame.size() && (p[0].revents & POLLOUT)) {
      const ssize_t w = ::send(proc_.channel_fd, frame.data() + sent, frame.size() - sent,
                               MSG_NOSIGNAL | MSG_DONTWAIT);
      if (w > 0)
        sent += static_cast<std::size_t>(w);
      else if (w < 0 && errno != EAGAIN && errno != EINTR) {
        fail(WorkerFault::Died, "", op);
        throw WorkerGone(failure_);
      }
    }
    if (p[0].revents & (POLLIN | POLLHUP | POLLERR)) {
      char buf[65536];
      const std::size_t want =
          have_head ? std::min<uint64_t>(sizeof buf, reply_len - body.size()) : 16 - head.size();
      const ssize_t n = want == 0 ? 0 : ::recv(proc_.channel_fd, buf, want, MSG_DONTWAIT);
      if (n == 0 && want != 0) {
        fail(WorkerFault::Died, "", op);
        throw WorkerGone(failure_);
      }
      if (n < 0 && errno != EAGAIN && errno != EINTR) {
        fail(WorkerFault::Died, "", op);
        throw WorkerGone(failure_);
      }
      if (n > 0) {
        if (!have_head) {
          head.append(buf, static_cast<std::size_t>(n));
          if (head.size() == 16) {
            uint32_t m;
            std::memcpy(&m, head.data(), 4);
            std::memcpy(&reply_code, head.data() + 4, 4);
            std::memcpy(&reply_len, head.data() + 8, 8);
            if (m != kWireMagic || reply_len > limit ||
                (reply_code != static_cast<uint32_t>(Reply::Ok) &&
                 reply_code != static_cast<uint32_t>(Reply::PluginError))) {
              fail(WorkerFault::Protocol,
                   "sent the grader a malformed reply (something wrote to the grader's channel, "
                   "file descriptor 3)",
                   op);
              throw WorkerGone(failure_);
            }
            have_head = true;
          }
        } else {
          body.append(buf, static_cast<std::size_t>(n));
        }
      }
    }
    if (have_head && body.size() == reply_len && sent == frame.size()) break;
  }
  drain_output();
  if (reply_code == static_cast<uint32_t>(Reply::PluginError)) {
    try {
      WireReader in(body);
      std::string msg = in.str();
      in.finish();
      throw PluginCallError(sanitize_text(msg));
    } catch (const WireError&) {
      fail(WorkerFault::Protocol, "sent the grader a malformed error reply", op);
      throw WorkerGone(failure_);
    }
  }
  return body;
}

std::shared_ptr<const LoadedPlugin> RemoteWorker::open(const std::string& name, uint32_t kind) {
  WireWriter out;
  out.str(name);
  out.u32(kind);
  const std::string reply = call(Op::Open, out.bytes(), 1u << 22);
  auto t = std::make_unique<Table>();
  try {
    WireReader in(reply);
    pinsim_plugin& p = t->table;
    p.abi_version = PINSIM_ABI_VERSION;
    p.struct_size = sizeof(pinsim_plugin);
    p.kind = in.u32();
    p.arity = in.u32();
    // Live inputs, outlines, constraints, parameter derivatives and Jacobian products are not
    // forwarded over the wire: the proxy never claims them (input, outline, constraint_set,
    // constraints, add_dforce_dparam, add_jacobian_products and add_adjoint_products stay
    // NULL), so the host refuses a play session, draws without outlines, runs the force
    // through add_force and forms products from the Jacobians' entries instead of calling
    // into nothing.
    p.capabilities = in.u32() & ~static_cast<uint32_t>(PINSIM_CAP_INPUTS | PINSIM_CAP_OUTLINES |
                                                       PINSIM_CAP_CONSTRAINTS | PINSIM_CAP_DPARAM |
                                                       PINSIM_CAP_JACOBIAN_PRODUCTS |
                                                       PINSIM_CAP_ADJOINT_PRODUCTS);
    const bool has_energy = in.u32() != 0, has_jac = in.u32() != 0, has_dist = in.u32() != 0;
    p.name = t->keep(sanitize_text(in.str(256)));
    p.version = t->keep(sanitize_text(in.str(256)));
    p.doc = t->keep(sanitize_text(in.str()));
    const std::string file = sanitize_text(in.str(4096));
    const uint32_t n_params = in.u32();
    if (n_params > 256) throw WireError("more than 256 parameters");
    if (p.kind != kind || std::string(p.name) != name) throw WireError("wrong plugin described");
    if (p.kind == PINSIM_KIND_FORCE && p.arity > 1u << 20)
      throw WireError("force arity " + std::to_string(p.arity) + " out of range");
    t->params.resize(n_params);
    for (auto& q : t->params) {
      q.name = t->keep(sanitize_text(in.str(256)));
      q.type = in.u32();
      q.flags = in.u32() & ~static_cast<uint32_t>(PINSIM_PARAM_DIFFERENTIABLE);
      q.default_value[0] = in.f64();
      q.default_value[1] = in.f64();
      const bool has_default = in.u32() != 0;
      std::string def = sanitize_text(in.str());
      q.default_string = has_default ? t->keep(std::move(def)) : nullptr;
      const bool has_choices = in.u32() != 0;
      std::string choices = sanitize_text(in.str());
      q.choices = has_choices ? t->keep(std::move(choices)) : nullptr;
      q.min = in.f64();
      q.max = in.f64();
      q.units = t->keep(sanitize_text(in.str(256)));
      q.doc = t->keep(sanitize_text(in.str()));
      if (q.type < PINSIM_PARAM_REAL || q.type > PINSIM_PARAM_VEC2)
        throw WireError("parameter of unknown type");
    }
    in.finish();
    p.params = t->params.data();
    p.n_params = n_params;
    p.create = r_create;
    p.destroy = r_destroy;
    if (p.kind == PINSIM_KIND_FORCE) {
      p.force.add_force = r_add_force;
      p.force.energy = has_energy ? r_energy : nullptr;
      p.force.add_jacobians = has_jac ? r_add_jacobians : nullptr;
    } else {
      p.backend.advance = r_advance;
      p.backend.distance = has_dist ? r_distance : nullptr;
    }
    // The worker checked its library's table; a forged description is checked here, before
    // any check can call through a pointer the flags promise.
    if (const std::string bad = plugin_table_problems(p); !bad.empty())
      throw PluginCallError("plugin '" + name + "' has an inconsistent table: " + bad);
    auto loaded = std::make_shared<LoadedPlugin>();
    loaded->table = &t->table;
    loaded->path = "submission/" + file;
    table_ = std::move(t);
    g_active = this;
    return loaded;
  } catch (const WireError& e) {
    fail(WorkerFault::Protocol,
         std::string("sent the grader a malformed description (") + e.what() + ")", Op::Open);
    throw WorkerGone(failure_);
  }
}

void RemoteWorker::finish() {
  if (fault_ == WorkerFault::None && proc_.pid > 0) {
    const double end = std::min(deadline_, steady_seconds() + 2.0);
    const double saved = deadline_;
    deadline_ = end;
    try {
      call(Op::Quit, "", kSmallReply);
    } catch (const std::exception&) {
    }
    deadline_ = saved;
  }
  if (g_active == this) g_active = nullptr;
  drain_output();
  if (proc_.pid > 0) {
    // Give a quitting worker a moment to exit by itself, then end the sandbox either way.
    int status = 0;
    for (int i = 0; i < 100; ++i) {
      const pid_t w = ::waitpid(proc_.pid, &status, WNOHANG);
      if (w == proc_.pid) {
        proc_.pid = -1;
        break;
      }
      drain_output();
      ::usleep(2000);
    }
  }
  drain_output();
  // Whether it exited by itself or not: the sandbox ends (the fallback sweeps its uid).
  kill_and_reap(proc_, false);
  if (proc_.output_fd >= 0) ::close(proc_.output_fd);
  if (proc_.channel_fd >= 0) ::close(proc_.channel_fd);
  proc_.output_fd = proc_.channel_fd = -1;
}

}  // namespace pinsim::grading
