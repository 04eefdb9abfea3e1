#include "core/plugin_instance.hpp"

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

void ForceInstance::add_jacobians(const pinsim_state_view& s, const pinsim_triplet_sink* dfdx,
                                  const pinsim_triplet_sink* dfdv) const {
  pinsim_error err = make_err(err_);
  if (plugin_->table->force.add_jacobians(self_, &s, dfdx, dfdv, &err) != 0) fail("add_jacobians");
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
