#include "grading/worker.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <map>
#include <string>
#include <vector>

#include "core/plugin_loader.hpp"
#include "grading/wire.hpp"

namespace fs = std::filesystem;

namespace pinsim::grading {
namespace {

constexpr uint64_t kMaxParticles = 1u << 24;

struct Error {
  std::string message;
};

/// The submission's library that declares plugin `name`, loaded; or an Error listing what
/// each library declares instead.
std::shared_ptr<const LoadedPlugin> open_plugin(const fs::path& dir, const std::string& name) {
  std::error_code ec;
  std::vector<fs::path> files;
  for (const auto& e : fs::directory_iterator(dir, ec))
    if (e.path().extension() == ".so") files.push_back(e.path());
  std::sort(files.begin(), files.end());
  std::string why;
  for (const auto& f : files) {
    try {
      auto p = load_plugin_file(f);
      if (p->name() == name) return p;
      why += "\n  " + f.filename().string() + " declares plugin '" + p->name() + "'";
    } catch (const std::exception& e) {
      why += "\n  " + f.filename().string() + ": " + e.what();
    }
  }
  throw Error{"no library of the submission declares plugin '" + name +
              "':" + (why.empty() ? " none was found" : why)};
}

void describe(WireWriter& w, const LoadedPlugin& p) {
  const pinsim_plugin& t = *p.table;
  w.u32(t.kind);
  w.u32(t.arity);
  w.u32(t.capabilities);
  w.u32(t.force.energy != nullptr);
  w.u32(t.force.add_jacobians != nullptr);
  w.u32(t.backend.distance != nullptr);
  const auto s = [](const char* c) { return std::string(c ? c : ""); };
  w.str(s(t.name));
  w.str(s(t.version));
  w.str(s(t.doc));
  w.str(p.path.filename().string());
  w.u32(t.n_params);
  for (uint32_t i = 0; i < t.n_params; ++i) {
    const pinsim_param& q = t.params[i];
    w.str(s(q.name));
    w.u32(q.type);
    w.u32(q.flags);
    w.f64(q.default_value[0]);
    w.f64(q.default_value[1]);
    w.u32(q.default_string != nullptr);
    w.str(s(q.default_string));
    w.u32(q.choices != nullptr);
    w.str(s(q.choices));
    w.f64(q.min);
    w.f64(q.max);
    w.str(s(q.units));
    w.str(s(q.doc));
  }
}

struct Triplets {
  WireWriter* w;
  uint32_t which;
  uint64_t* count;
};

void add_triplet(void* ctx, uint32_t row, uint32_t col, double value) {
  auto* t = static_cast<Triplets*>(ctx);
  t->w->u32(t->which);
  t->w->u32(row);
  t->w->u32(col);
  t->w->u32(0);
  t->w->f64(value);
  ++*t->count;
}

struct Events {
  WireWriter w;
  uint64_t count = 0;
};

void emit_event(void* ctx, const pinsim_event* e) {
  auto* ev = static_cast<Events*>(ctx);
  ev->w.f64(e->t);
  ev->w.i64(e->particle);
  ev->w.i64(e->obstacle);
  ev->w.i64(e->other);
  ev->w.f64s(e->point, 2);
  ev->w.f64s(e->normal, 2);
  ev->w.f64(e->vn_before);
  ev->w.f64(e->vn_after);
  ++ev->count;
}

class Worker {
 public:
  explicit Worker(fs::path libraries) : libraries_(std::move(libraries)) {}

  /// One request; fills `out` and returns the reply code.
  Reply handle(Op op, WireReader& in, WireWriter& out) {
    std::vector<char> msg(4096, '\0');
    pinsim_error err{msg.data(), static_cast<uint32_t>(msg.size())};
    const auto failed = [&](const char* what) {
      out.bytes().clear();
      out.str(std::string(what) + " failed: " +
              (msg[0] ? std::string(msg.data(), strnlen(msg.data(), msg.size())) : "no message"));
      return Reply::PluginError;
    };
    switch (op) {
      case Op::Open: {
        const std::string name = in.str();
        const uint32_t kind = in.u32();
        plugin_ = open_plugin(libraries_, name);
        if (plugin_->table->kind != kind)
          throw Error{"plugin '" + name + "' is a " +
                      (plugin_->is_force() ? "force" : "collision backend") +
                      ", this assignment wants a " +
                      (kind == PINSIM_KIND_FORCE ? "force" : "backend")};
        describe(out, *plugin_);
        return Reply::Ok;
      }
      case Op::Create: {
        need_plugin();
        const std::string params = in.str(1u << 24), scene = in.str(1u << 28);
        WireState s;
        s.read(in, kMaxParticles);
        const uint32_t arity = in.u32();
        const uint64_t n_el = in.u64(), words = in.u64();
        in.need(words * sizeof(uint32_t));
        std::vector<uint32_t> el(words);
        in.raw(el.data(), el.size() * sizeof(uint32_t));
        const std::string context = in.str();
        const pinsim_state_view v = s.view();
        pinsim_create_args a{
            params.c_str(), scene.empty() ? nullptr : scene.c_str(), &v, el.data(), n_el, arity,
            context.c_str()};
        void* self = plugin_->table->create(&a, &err);
        if (self == nullptr) return failed("create");
        instances_[++last_id_] = self;
        out.u64(last_id_);
        return Reply::Ok;
      }
      case Op::Destroy: {
        void* self = instance(in.u64());
        instances_.erase(last_looked_up_);
        plugin_->table->destroy(self);
        return Reply::Ok;
      }
      case Op::AddForce: {
        void* self = instance(in.u64());
        WireState s;
        s.read(in, kMaxParticles);
        std::vector<double> f(2 * s.n);
        in.f64s(f.data(), f.size());
        const pinsim_state_view v = s.view();
        if (plugin_->table->force.add_force(self, &v, f.data(), &err) != 0)
          return failed("add_force");
        out.f64s(f.data(), f.size());
        return Reply::Ok;
      }
      case Op::Energy: {
        void* self = instance(in.u64());
        WireState s;
        s.read(in, kMaxParticles);
        const pinsim_state_view v = s.view();
        double e = 0.0;
        if (plugin_->table->force.energy == nullptr) throw Error{"the plugin has no energy()"};
        if (plugin_->table->force.energy(self, &v, &e, &err) != 0) return failed("energy");
        out.f64(e);
        return Reply::Ok;
      }
      case Op::Jacobians: {
        void* self = instance(in.u64());
        WireState s;
        s.read(in, kMaxParticles);
        const bool want_x = in.u32() != 0, want_v = in.u32() != 0;
        if (plugin_->table->force.add_jacobians == nullptr)
          throw Error{"the plugin has no add_jacobians()"};
        uint64_t count = 0;
        WireWriter entries;
        Triplets tx{&entries, 0, &count}, tv{&entries, 1, &count};
        pinsim_triplet_sink sx{&tx, add_triplet, nullptr}, sv{&tv, add_triplet, nullptr};
        const pinsim_state_view v = s.view();
        if (plugin_->table->force.add_jacobians(self, &v, want_x ? &sx : nullptr,
                                                want_v ? &sv : nullptr, &err) != 0)
          return failed("add_jacobians");
        out.u64(count);
        out.raw(entries.bytes().data(), entries.bytes().size());
        return Reply::Ok;
      }
      case Op::Advance: {
        void* self = instance(in.u64());
        WireState s;
        s.read(in, kMaxParticles);
        const double dt = in.f64();
        pinsim_state_mut m{s.n, s.t, s.x.data(), s.v.data(), s.inv_mass.data(), s.radius.data()};
        Events ev;
        pinsim_event_sink sink{&ev, emit_event};
        if (plugin_->table->backend.advance(self, &m, dt, &sink, &err) != 0)
          return failed("advance");
        out.f64s(s.x.data(), s.x.size());
        out.f64s(s.v.data(), s.v.size());
        out.u64(ev.count);
        out.raw(ev.w.bytes().data(), ev.w.bytes().size());
        return Reply::Ok;
      }
      case Op::Distance: {
        void* self = instance(in.u64());
        double p[2];
        in.f64s(p, 2);
        const double t = in.f64();
        if (plugin_->table->backend.distance == nullptr)
          throw Error{"the backend has no distance()"};
        double d = 0.0;
        int64_t obstacle = -1;
        if (plugin_->table->backend.distance(self, p, t, &d, &obstacle, &err) != 0)
          return failed("distance");
        out.f64(d);
        out.i64(obstacle);
        return Reply::Ok;
      }
      case Op::Quit:
        return Reply::Ok;
    }
    throw Error{"unknown request"};
  }

 private:
  void need_plugin() const {
    if (!plugin_) throw Error{"no plugin opened"};
  }
  void* instance(uint64_t id) {
    need_plugin();
    const auto it = instances_.find(id);
    if (it == instances_.end()) throw Error{"no instance " + std::to_string(id)};
    last_looked_up_ = id;
    return it->second;
  }

  fs::path libraries_;
  std::shared_ptr<const LoadedPlugin> plugin_;
  std::map<uint64_t, void*> instances_;
  uint64_t last_id_ = 0, last_looked_up_ = 0;
};

}  // namespace

int serve_worker(int fd, const fs::path& libraries) {
  // What the submission prints reaches the grader's capture before the reply it belongs to.
  std::setvbuf(stdout, nullptr, _IOLBF, 0);
  Worker w(libraries);
  for (;;) {
    uint32_t code = 0;
    std::string payload;
    if (!read_frame(fd, code, payload)) return 0;  // the grader went away
    WireWriter out;
    Reply r;
    try {
      WireReader in(payload);
      r = w.handle(static_cast<Op>(code), in, out);
    } catch (const Error& e) {
      out.bytes().clear();
      out.str(e.message.substr(0, kMaxWireString));
      r = Reply::PluginError;
    } catch (const std::bad_alloc&) {
      out.bytes().clear();
      out.str("ran out of memory");
      r = Reply::PluginError;
    } catch (const std::exception& e) {
      out.bytes().clear();
      out.str(std::string(e.what()).substr(0, kMaxWireString));
      r = Reply::PluginError;
    }
    std::cout.flush();
    std::cerr.flush();
    std::fflush(nullptr);
    if (!write_frame(fd, static_cast<uint32_t>(r), out.bytes())) return 0;
    if (static_cast<Op>(code) == Op::Quit) return 0;
  }
}

}  // namespace pinsim::grading
