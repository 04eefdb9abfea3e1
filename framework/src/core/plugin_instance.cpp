#include "core/plugin_instance.hpp"

#include <fmt/format.h>

#include <string>

#include "core/bodies.hpp"

namespace pinsim {
namespace {

constexpr uint32_t kErrCap = 2048;

pinsim_error make_err(std::vector<char>& buf) {
  if (buf.size() != kErrCap) buf.assign(kErrCap, '\0');
  buf[0] = '\0';
  return {buf.data(), kErrCap};
}

void* create_instance(const LoadedPlugin& p, const State& initial, const InstanceArgs& a,
                      const std::string& scene_json, std::vector<char>& err_buf) {
  const std::string params = a.params.dump();
  const pinsim_state_view view = initial.view();
  pinsim_create_args args{};
  args.params_json = params.c_str();
  args.scene_json = a.scene.is_null() ? nullptr : scene_json.c_str();
  args.initial = &view;
  args.elements = a.elements.empty() ? nullptr : a.elements.data();
  args.arity = p.table->arity;
  args.n_elements = element_count(a.elements, args.arity);
  args.context = a.context.c_str();
  pinsim_error err = make_err(err_buf);
  void* self = p.table->create(&args, &err);
  if (self == nullptr) {
    std::string msg = err_buf.data();
    if (msg.empty()) msg = "create() failed without a message";
    if (msg.rfind(a.context, 0) != 0) msg = a.context + ": plugin '" + p.name() + "': " + msg;
    throw PluginError(msg);
  }
  return self;
}

}  // namespace

ForceInstance::ForceInstance(std::shared_ptr<const LoadedPlugin> plugin, const State& initial,
                             InstanceArgs args)
    : plugin_(std::move(plugin)), context_(args.context), elements_(args.elements) {
  self_ = create_instance(*plugin_, initial, args, "", err_);
}

ForceInstance::~ForceInstance() {
  if (self_ != nullptr) plugin_->table->destroy(self_);
}

void ForceInstance::fail(const char* what) const {
  throw PluginError(context_ + ": plugin '" + plugin_->name() + "' " + what +
                    " failed: " + err_.data());
}

void ForceInstance::add_force(const pinsim_state_view& s, double* f) const {
  pinsim_error err = make_err(err_);
  if (plugin_->table->force.add_force(self_, &s, f, &err) != 0) fail("add_force");
}

double ForceInstance::energy(const pinsim_state_view& s) const {
  pinsim_error err = make_err(err_);
  double e = 0.0;
  if (plugin_->table->force.energy(self_, &s, &e, &err) != 0) fail("energy");
  return e;
}

namespace {

/// A sink between a plugin and the host's sink that passes on only entries inside the
/// state (rows and columns below 2n, block particles below n): a plugin's stray index must
/// not reach a host array. The first entry outside is kept for the error message; the
/// caller throws after the plugin returns (an exception must not cross the plugin's C ABI).
struct BoundedSink {
  const pinsim_triplet_sink* to;
  uint64_t n;  ///< particles
  const char* which;
  std::string bad;

  void add(uint32_t row, uint32_t col, double value) {
    if (row >= 2 * n || col >= 2 * n) {
      if (bad.empty())
        bad = fmt::format("its {} has an entry at row {}, column {}", which, row, col);
      return;
    }
    to->add(to->context, row, col, value);
  }
  void add_blocks(const uint32_t* particles, const double* values, uint64_t count) {
    for (uint64_t q = 0; q < count; ++q)
      if (particles[2 * q] >= n || particles[2 * q + 1] >= n) {
        if (bad.empty())
          bad = fmt::format("its {} has a 2x2 block at particles ({}, {})", which, particles[2 * q],
                            particles[2 * q + 1]);
        return;  // the whole batch: none of it reaches the host
      }
    to->add_blocks(to->context, particles, values, count);
  }
  pinsim_triplet_sink sink() {
    pinsim_triplet_sink s{this,
                          [](void* c, uint32_t row, uint32_t col, double value) {
                            static_cast<BoundedSink*>(c)->add(row, col, value);
                          },
                          nullptr};
    // Without the host's add_blocks the plugin must fall back to add() (ABI 4), as before.
    if (to->add_blocks != nullptr)
      s.add_blocks = [](void* c, const uint32_t* particles, const double* values, uint64_t count) {
        static_cast<BoundedSink*>(c)->add_blocks(particles, values, count);
      };
    return s;
  }
};

}  // namespace

void ForceInstance::add_jacobians(const pinsim_state_view& s, const pinsim_triplet_sink* dfdx,
                                  const pinsim_triplet_sink* dfdv) const {
  pinsim_error err = make_err(err_);
  BoundedSink bx{dfdx, s.n, "df/dx", {}}, bv{dfdv, s.n, "df/dv", {}};
  const pinsim_triplet_sink sx = dfdx ? bx.sink() : pinsim_triplet_sink{},
                            sv = dfdv ? bv.sink() : pinsim_triplet_sink{};
  if (plugin_->table->force.add_jacobians(self_, &s, dfdx ? &sx : nullptr, dfdv ? &sv : nullptr,
                                          &err) != 0)
    fail("add_jacobians");
  for (const BoundedSink* b : {&bx, &bv})
    if (!b->bad.empty())
      throw PluginError(fmt::format(
          "{}: plugin '{}' add_jacobians: {}, outside the state (rows and columns must be "
          "below {}, block particles below {}: {} particles)",
          context_, plugin_->name(), b->bad, 2 * s.n, s.n, s.n));
}

pinsim_constraint_set ForceInstance::constraint_set() const {
  pinsim_error err = make_err(err_);
  pinsim_constraint_set out{};
  if (plugin_->table->constraint_set(self_, &out, &err) != 0) fail("constraint_set");
  return out;
}

void ForceInstance::constraints(const double* x, const uint64_t* which, uint64_t count, double* c,
                                double* dc) const {
  char buf[512];
  buf[0] = '\0';
  pinsim_error err{buf, sizeof buf};
  if (plugin_->table->constraints(self_, x, which, count, c, dc, &err) != 0)
    throw PluginError(context_ + ": plugin '" + plugin_->name() + "' constraints failed: " + buf);
}

int64_t ForceInstance::dparam_index(const std::string& name) const {
  const pinsim_plugin& t = *plugin_->table;
  if (t.add_dforce_dparam == nullptr || !has_cap(PINSIM_CAP_DPARAM)) return -1;
  for (uint32_t i = 0; i < t.n_params; ++i)
    if (t.params[i].name != nullptr && name == t.params[i].name)
      return (t.params[i].flags & PINSIM_PARAM_DIFFERENTIABLE) ? static_cast<int64_t>(i) : -1;
  return -1;
}

void ForceInstance::add_dforce_dparam(const pinsim_state_view& s, uint32_t param,
                                      uint32_t component, double* df) const {
  pinsim_error err = make_err(err_);
  if (plugin_->table->add_dforce_dparam(self_, &s, param, component, df, &err) != 0)
    fail("add_dforce_dparam");
}

uint32_t ForceInstance::dparam_slot(uint32_t param, uint32_t component) const {
  const pinsim_plugin& t = *plugin_->table;
  uint32_t slot = 0;
  for (uint32_t i = 0; i < param && i < t.n_params; ++i)
    if (t.params[i].flags & PINSIM_PARAM_DIFFERENTIABLE)
      slot += t.params[i].type == PINSIM_PARAM_VEC2 ? 2u : 1u;
  return slot + component;
}

uint32_t ForceInstance::dparam_slots() const { return dparam_slot(plugin_->table->n_params, 0); }

void ForceInstance::add_adjoint_products(const pinsim_state_view& s, const double* w, double* gx,
                                         double* gv, double* gp) const {
  pinsim_error err = make_err(err_);
  if (plugin_->table->add_adjoint_products(self_, &s, w, gx, gv, gp, &err) != 0)
    fail("add_adjoint_products");
}

void ForceInstance::add_jacobian_products(const pinsim_state_view& s, const double* w, double* gx,
                                          double* gv) const {
  pinsim_error err = make_err(err_);
  if (plugin_->table->add_jacobian_products(self_, &s, w, gx, gv, &err) != 0)
    fail("add_jacobian_products");
}

BackendInstance::BackendInstance(std::shared_ptr<const LoadedPlugin> plugin, const State& initial,
                                 InstanceArgs args)
    : plugin_(std::move(plugin)), context_(args.context) {
  self_ = create_instance(*plugin_, initial, args, args.scene.dump(), err_);
}

BackendInstance::~BackendInstance() {
  if (self_ != nullptr) plugin_->table->destroy(self_);
}

void BackendInstance::fail(const char* what) const {
  throw PluginError(context_ + ": backend '" + plugin_->name() + "' " + what +
                    " failed: " + err_.data());
}

void BackendInstance::advance(State& s, double dt, const pinsim_event_sink* events) {
  pinsim_error err = make_err(err_);
  pinsim_state_mut m = s.mut();
  if (plugin_->table->backend.advance(self_, &m, dt, events, &err) != 0) fail("advance");
}

double BackendInstance::distance(double x, double y, double t, int64_t* obstacle) const {
  pinsim_error err = make_err(err_);
  const double p[2] = {x, y};
  double d = 0.0;
  if (plugin_->table->backend.distance(self_, p, t, &d, obstacle, &err) != 0) fail("distance");
  return d;
}

OutlineReport BackendInstance::outline(const State& s, double tolerance) const {
  if (!has_outline())
    throw PluginError(context_ + ": backend '" + plugin_->name() +
                      "' does not report its obstacles' outlines (no PINSIM_CAP_OUTLINES)");
  OutlineReport out;
  pinsim_outline_sink sink{&out, [](void* context, const pinsim_outline* o) {
                             auto* r = static_cast<OutlineReport*>(context);
                             OutlineReport::Obstacle ob;
                             ob.index = o->obstacle;
                             ob.id = o->id != nullptr ? o->id : "";
                             ob.bounds = o->bounds;
                             ob.sweep = o->sweep;
                             const double* p = o->points;
                             for (uint32_t k = 0; k < o->n_rings; ++k) {
                               std::vector<Eigen::Vector2d> ring(o->ring_sizes[k]);
                               for (auto& q : ring) {
                                 q = Eigen::Vector2d(p[0], p[1]);
                                 p += 2;
                               }
                               ob.rings.push_back(std::move(ring));
                             }
                             r->obstacles.push_back(std::move(ob));
                           }};
  pinsim_error err = make_err(err_);
  const pinsim_state_view v = s.view();
  if (plugin_->table->backend.outline(self_, &v, tolerance, &sink, &out.bounds, &out.sweep, &err) !=
      0)
    fail("outline");
  return out;
}

void BackendInstance::record_drift(const pinsim_drift_sink* sink) {
  if (!can_record_drift())
    throw PluginError(context_ + ": backend '" + plugin_->name() +
                      "' does not record its drifts (no record_drift)");
  pinsim_error err = make_err(err_);
  if (plugin_->table->record_drift(self_, sink, &err) != 0) fail("record_drift");
}

void BackendInstance::input(const std::string& name, bool pressed, double t) {
  if (!has_input())
    throw PluginError(context_ + ": backend '" + plugin_->name() +
                      "' does not take live inputs (no PINSIM_CAP_INPUTS), so input \"" + name +
                      "\" cannot change between steps");
  pinsim_error err = make_err(err_);
  if (plugin_->table->backend.input(self_, name.c_str(), pressed ? 1 : 0, t, &err) != 0)
    fail("input");
}

}  // namespace pinsim
