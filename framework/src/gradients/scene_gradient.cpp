#include "gradients/scene_gradient.hpp"

#include <fmt/format.h>

#include <Eigen/SparseCore>
#include <algorithm>
#include <chrono>
#include <map>
#include <optional>
#include <utility>

#include "core/format.hpp"
#include "core/input_error.hpp"
#include "core/instances.hpp"
#include "core/integrator.hpp"
#include "core/integrators.hpp"
#include "core/set_path.hpp"
#include "gradients/checkpoints.hpp"
#include "gradients/drift_record.hpp"

namespace pinsim::grad {
namespace {

using Clock = std::chrono::steady_clock;

/// The most a replayed segment may end from the forward run, relative to the state's size.
constexpr double kReplayTolerance = 1e-9;

double seconds_since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

bool parse_index(const std::string& s, std::size_t& out) {
  if (s.empty() || s.size() > 9 || s.find_first_not_of("0123456789") != std::string::npos)
    return false;
  out = std::stoul(s);
  return true;
}

constexpr const char* kDifferentiable =
    "differentiable: particles[I].x, particles[I].v (explicit particles' initial state), "
    "bodies[K].center (.origin, .root: the body's position), bodies[K].velocity, "
    "forces[K].params.NAME (a real or 2-vector parameter) and, with a backend that records its "
    "collisions (sdf), obstacles[K].material.restitution, .friction, .kick";

[[noreturn]] void bad_path(const std::string& path, const std::string& what) {
  throw InputError("--wrt " + path + ": " + what);
}

/// An obstacle's material value (restitution, friction or kick), with its value (the scene's
/// or the default) and bounds (scene_field's material: e in [0, 1], mu >= 0, kick >= 0).
WrtValue material_value(const Scene& scene, const Simulation& sim, const std::string& path,
                        const std::vector<std::string>& k) {
  if (!sim.backend().can_record_drift())
    bad_path(path,
             "not differentiable: obstacle materials need a backend that records its "
             "collisions for the adjoint, and backend '" +
                 sim.backend().plugin().name() + "' does not (" + kDifferentiable + ")");
  const nlohmann::json& obs =
      scene.doc.contains("obstacles") ? scene.doc["obstacles"] : nlohmann::json::array();
  std::size_t o = 0;
  if (k.size() != 4 || !parse_index(k[1], o) || k[2] != "material" ||
      (k[3] != "restitution" && k[3] != "friction" && k[3] != "kick"))
    bad_path(path, "expected obstacles[K].material.restitution, .friction or .kick");
  if (!obs.is_array() || o >= obs.size())
    bad_path(path, "the scene has " + std::to_string(obs.is_array() ? obs.size() : 0) +
                       " obstacles, no index " + k[1]);
  WrtValue w;
  w.path = path;
  w.kind = WrtValue::Kind::kMaterial;
  w.index = o;
  w.param = k[3];
  double v = k[3] == "restitution" ? 1.0 : 0.0;
  const nlohmann::json& ob = obs[o];
  if (ob.contains("material") && ob["material"].contains(k[3]))
    v = ob["material"][k[3]].get<double>();
  w.value = {v};
  w.lower = 0.0;
  if (k[3] == "restitution") w.upper = 1.0;
  return w;
}

/// A particle's initial position or velocity.
WrtValue particle_value(const Scene& scene, const std::string& path,
                        const std::vector<std::string>& k) {
  const std::size_t explicit_count =
      scene.doc.contains("particles") && scene.doc["particles"].is_array()
          ? scene.doc["particles"].size()
          : 0;
  std::size_t i = 0;
  if (k.size() < 2 || !parse_index(k[1], i))
    bad_path(path, "expected particles[I].x or particles[I].v");
  if (i >= explicit_count)
    bad_path(path, "the scene's \"particles\" has " + std::to_string(explicit_count) +
                       " entries, no index " + k[1] +
                       " (bodies' particles are not named by particles[I])");
  if (k.size() != 3 || (k[2] != "x" && k[2] != "v"))
    bad_path(path,
             "not differentiable: a particle's x or v is (" + std::string(kDifferentiable) + ")");
  WrtValue w;
  w.path = path;
  w.kind = k[2] == "x" ? WrtValue::Kind::kPosition : WrtValue::Kind::kVelocity;
  w.index = i;
  w.particles = {static_cast<uint32_t>(i)};
  const Eigen::Vector2d q = k[2] == "x" ? scene.particles.x[i] : scene.particles.v[i];
  w.value = {q.x(), q.y()};
  return w;
}

/// A body's position (the key its type is built from: a ring blob's center, a grid blob's
/// origin, a strand's root), which moves all its particles, or its velocity, which every
/// particle that is not pinned starts with.
WrtValue body_value(const Scene& scene, const std::string& path,
                    const std::vector<std::string>& k) {
  std::size_t b = 0;
  if (k.size() < 2 || !parse_index(k[1], b))
    bad_path(path, "expected bodies[K].center (.origin, .root) or bodies[K].velocity");
  if (b >= scene.bodies.size())
    bad_path(path,
             "the scene has " + std::to_string(scene.bodies.size()) + " bodies, no index " + k[1]);
  const Body& body = scene.bodies[b];
  const std::string place = body.type == "ring_blob"   ? "center"
                            : body.type == "grid_blob" ? "origin"
                            : body.type == "strand"    ? "root"
                                                       : "";
  if (k.size() != 3 || (k[2] != "velocity" && (place.empty() || k[2] != place)))
    bad_path(path, "not differentiable: a " + body.type + "'s " +
                       (place.empty() ? std::string() : place + " or ") + "velocity is (" +
                       kDifferentiable + ")");
  const nlohmann::json& spec = scene.doc["bodies"][b];
  WrtValue w;
  w.path = path;
  w.index = b;
  w.param = k[2];
  const bool velocity = k[2] == "velocity";
  w.kind = velocity ? WrtValue::Kind::kBodyVelocity : WrtValue::Kind::kBodyPosition;
  w.value = {0.0, 0.0};
  if (spec.contains(k[2])) w.value = spec[k[2]].get<std::vector<double>>();
  for (uint32_t i = body.first; i < body.first + body.count; ++i)
    if (!velocity || scene.particles.inv_mass[i] > 0.0) w.particles.push_back(i);
  return w;
}

/// A force's real or 2-vector parameter, with its value (the scene's or the default) and
/// its bounds from the plugin's table.
WrtValue force_value(const Scene& scene, const Simulation& sim, const std::string& path,
                     const std::vector<std::string>& k) {
  std::size_t f = 0;
  if (k.size() < 2 || !parse_index(k[1], f)) bad_path(path, "expected forces[K].params.NAME");
  if (f >= sim.forces().size())
    bad_path(path,
             "the scene has " + std::to_string(sim.forces().size()) + " forces, no index " + k[1]);
  if (k.size() != 4 || k[2] != "params")
    bad_path(path, "not differentiable (" + std::string(kDifferentiable) + ")");
  const pinsim_plugin& t = *sim.forces()[f]->plugin().table;
  const pinsim_param* decl = nullptr;
  std::string names;
  for (uint32_t j = 0; j < t.n_params; ++j) {
    names += (j ? ", " : "") + std::string(t.params[j].name);
    if (k[3] == t.params[j].name) decl = &t.params[j];
  }
  if (decl == nullptr)
    bad_path(path, "plugin '" + std::string(t.name) + "' has no parameter '" + k[3] +
                       "' (its parameters: " + names + ")");
  if (decl->type != PINSIM_PARAM_REAL && decl->type != PINSIM_PARAM_VEC2)
    bad_path(path, "not differentiable: parameter '" + k[3] + "' of plugin '" + t.name +
                       "' is not a real number or a 2-vector");
  WrtValue w;
  w.path = path;
  w.kind = WrtValue::Kind::kForceParameter;
  w.index = f;
  w.param = k[3];
  // bounds as the fit keeps them: an exclusive one moved inside by a relative 1e-12
  w.lower = decl->min;
  w.upper = decl->max;
  if ((decl->flags & PINSIM_PARAM_MIN_EXCLUSIVE) && std::isfinite(w.lower))
    w.lower += 1e-12 * std::max(std::abs(w.lower), 1.0);
  if ((decl->flags & PINSIM_PARAM_MAX_EXCLUSIVE) && std::isfinite(w.upper))
    w.upper -= 1e-12 * std::max(std::abs(w.upper), 1.0);
  const nlohmann::json& given = scene.forces[f].params;
  const int n = decl->type == PINSIM_PARAM_VEC2 ? 2 : 1;
  for (int c = 0; c < n; ++c) {
    double v = decl->default_value[c];
    if (given.contains(w.param)) {
      const nlohmann::json& g = given[w.param];
      v = n == 2 ? g.at(static_cast<std::size_t>(c)).get<double>() : g.get<double>();
    }
    w.value.push_back(v);
  }
  return w;
}

/// A sink that adds J^T w into `out` as a force emits J's entries: for an entry (r, c, J_rc),
/// out_c += J_rc w_r; for a 2x2 block d f_i / d x_j (column-major), out_j += block^T w_i.
struct TransposedProduct {
  const double* w;
  double* out;
  pinsim_triplet_sink sink() {
    return {this,
            [](void* p, uint32_t row, uint32_t col, double value) {
              auto* t = static_cast<TransposedProduct*>(p);
              t->out[col] += value * t->w[row];
            },
            [](void* p, const uint32_t* particles, const double* v, uint64_t count) {
              auto* t = static_cast<TransposedProduct*>(p);
              const double* w = t->w;
              double* out = t->out;
              for (uint64_t k = 0; k < count; ++k, v += 4) {
                // w_i read before out_j is written (they may be the same particle's)
                const std::size_t i = 2 * static_cast<std::size_t>(particles[2 * k]);
                const std::size_t j = 2 * static_cast<std::size_t>(particles[2 * k + 1]);
                const double w0 = w[i], w1 = w[i + 1];
                const double o0 = v[0] * w0 + v[1] * w1, o1 = v[2] * w0 + v[3] * w1;
                out[j] += o0;
                out[j + 1] += o1;
              }
            }};
  }
};

/// One component that a force depends on outside the state: a parameter of force `force`,
/// or (force -1) an initial position, which rest lengths and angles come from.
struct ParamSlot {
  std::size_t wrt = 0;  ///< index into the resolved values
  int component = 0;
  int64_t force = -1;
  std::size_t particle = 0;
  double value = 0.0;
};

/// The forces of a Simulation as a ForceModel: values and Jacobians from the plugins (their
/// Jacobian entries, or the host's finite differences for a plugin without them), and their
/// derivatives in parameters from the plugin's add_dforce_dparam where it gives the parameter's
/// (ABI 4.4), else by central differences of instances created with the parameter moved by
/// +-eps:
///   d f / d theta = (f(theta + eps) - f(theta - eps)) / (2 eps) + O(eps^2),
/// one-sided where theta - eps or theta + eps is outside the parameter's bounds.
class SimulationForces : public ForceModel {
 public:
  SimulationForces(Simulation& sim, const Scene& scene, PluginLoader& loader,
                   const std::vector<WrtValue>& wrt, double rel_eps, bool plugin_derivatives)
      : sim_(sim), plugin_derivatives_(plugin_derivatives) {
    for (const auto& f : sim.forces())
      if (!f->provides_dfdx() || (f->velocity_dependent() && !f->provides_dfdv()))
        all_exact_ = false;
    for (std::size_t w = 0; w < wrt.size(); ++w) {
      const WrtValue& v = wrt[w];
      for (std::size_t c = 0; c < v.value.size(); ++c) {
        if (v.kind == WrtValue::Kind::kVelocity || v.kind == WrtValue::Kind::kBodyVelocity ||
            v.kind == WrtValue::Kind::kMaterial)
          continue;
        const double theta = v.value[c];
        const double eps = rel_eps * std::max(std::abs(theta), 1.0);
        const double up = std::min(theta + eps, v.upper), down = std::max(theta - eps, v.lower);
        slot_index_.push_back({w, static_cast<int>(c), slots_});
        if (v.kind == WrtValue::Kind::kForceParameter) {
          add_parameter(scene, loader, w, v, static_cast<int>(c), up, down);
        } else {
          add_rest_source(scene, loader, w, v, static_cast<int>(c), up, down);
        }
        ++slots_;
      }
    }
    plan_fused_products();
  }

  /// Number of parameter components (gp's size).
  Eigen::Index slots() const { return slots_; }
  /// The slot of resolved value w's component c, or -1 (velocities have none).
  Eigen::Index slot_of(std::size_t w, int c) const {
    for (const SlotIndex& e : slot_index_)
      if (e.wrt == w && e.component == c) return e.slot;
    return -1;
  }
  uint64_t extra_force_evals() const { return extra_evals_; }
  /// Calls of a plugin's add_dforce_dparam.
  uint64_t dparam_evals() const { return dparam_evals_; }
  /// Calls of a plugin's add_adjoint_products.
  uint64_t fused_evals() const { return fused_evals_; }
  /// Whether resolved value w's parameter derivative comes from its plugin.
  bool from_plugin(std::size_t w) const {
    for (const Entry& e : entries_)
      if (e.wrt == w) return e.dparam >= 0;
    return false;
  }

  void force(const State& s, Eigen::Matrix2Xd& f) override { sim_.compute_forces(s, f); }

  void vjp(const State& s, const Eigen::Matrix2Xd& w, Eigen::Matrix2Xd& gx,
           Eigen::Matrix2Xd& gv) override {
    if (all_exact_) {
      vjp_part(Part::kAll, s, w, gx, gv);
      return;
    }
    cache(s);
    const Eigen::Map<const Eigen::VectorXd> wf(w.data(), w.size());
    Eigen::Map<Eigen::VectorXd>(gx.data(), gx.size()) += k_.transpose() * wf;
    Eigen::Map<Eigen::VectorXd>(gv.data(), gv.size()) += d_.transpose() * wf;
  }

  void param_vjp(const State& s, const Eigen::Matrix2Xd& w, Eigen::VectorXd& gp) override {
    param_vjp_part(Part::kAll, s, w, gp);
  }

  /// With every force's Jacobians from its plugin: the products force by force.
  bool splits() const override { return all_exact_; }

  void vjp_part(Part part, const State& s, const Eigen::Matrix2Xd& w, Eigen::Matrix2Xd& gx,
                Eigen::Matrix2Xd& gv) override {
    if (!all_exact_) {
      ForceModel::vjp_part(part, s, w, gx, gv);
      return;
    }
    // the plugins' products (ABI 4.4), or their entries straight into the products, no
    // matrix assembled; a force that depends on the positions only has df/dv = 0
    const pinsim_state_view view = s.view();
    for (const auto& f : sim_.forces())
      if (in_part(*f, part)) product(*f, part, view, w, gx, gv);
  }

  void param_vjp_part(Part part, const State& s, const Eigen::Matrix2Xd& w,
                      Eigen::VectorXd& gp) override {
    param_products(part, s, w, gp, false);
  }

  /// With every force's Jacobians from its plugin: a force that gives its products and its
  /// parameters' in one call (ABI 4.5) makes one call for both.
  void vjp_with_params(Part part, const State& s, const Eigen::Matrix2Xd& w, Eigen::Matrix2Xd& gx,
                       Eigen::Matrix2Xd& gv, Eigen::VectorXd& gp) override {
    if (!all_exact_ || fused_slots_.empty()) {
      ForceModel::vjp_with_params(part, s, w, gx, gv, gp);
      return;
    }
    const pinsim_state_view view = s.view();
    for (std::size_t i = 0; i < sim_.forces().size(); ++i) {
      const ForceInstance& f = *sim_.forces()[i];
      if (!in_part(f, part)) continue;
      if (fused_slots_[i] == 0) {
        product(f, part, view, w, gx, gv);
        continue;
      }
      const bool with_v = f.provides_dfdv() && part != Part::kPositionOnly;
      fused_gp_.assign(fused_slots_[i], 0.0);
      f.add_adjoint_products(view, w.data(), gx.data(), with_v ? gv.data() : nullptr,
                             fused_gp_.data());
      for (const Entry& e : entries_)
        if (e.force == i) gp[e.slot] += fused_gp_[e.fused_slot];
      ++fused_evals_;
    }
    param_products(part, s, w, gp, true);
  }

  /// With every differenced instance's Jacobians from its plugin: one central difference in
  /// the parameter of w^T (K a + D c), from the instances' exact Jacobians (no nested
  /// differences); else the default.
  void param_jacobian_vjp(const State& s, const Eigen::Matrix2Xd& w, const Eigen::Matrix2Xd& a,
                          const Eigen::Matrix2Xd& c, double eps, Eigen::VectorXd& gp) override {
    // every derivative from its plugin: differences of those along (a, c), no difference in
    // a parameter at all
    if (std::all_of(entries_.begin(), entries_.end(),
                    [](const Entry& e) { return e.dparam >= 0; })) {
      ForceModel::param_jacobian_vjp(s, w, a, c, eps, gp);
      return;
    }
    for (const Entry& e : entries_) {
      const ForceInstance& f = *sim_.forces()[e.force];
      if (!f.provides_dfdx() || (f.velocity_dependent() && !f.provides_dfdv())) {
        ForceModel::param_jacobian_vjp(s, w, a, c, eps, gp);
        return;
      }
    }
    for (const Entry& e : entries_) {
      const ForceInstance& minus = e.minus ? *e.minus : *sim_.forces()[e.force];
      const double yp = jacobian_product(*e.plus, s, w, a, c);
      const double ym = jacobian_product(minus, s, w, a, c);
      gp[e.slot] += (yp - ym) / e.denominator;
    }
  }

  bool velocity_dependent() const override {
    for (const auto& f : sim_.forces())
      if (f->velocity_dependent()) return true;
    return false;
  }

 private:
  /// gx += (df/dx)^T w, and gv += (df/dv)^T w unless `part` is the position-only forces', of
  /// force f: its plugin's products, or its entries straight into the products (no matrix
  /// assembled).
  static void product(const ForceInstance& f, Part part, const pinsim_state_view& view,
                      const Eigen::Matrix2Xd& w, Eigen::Matrix2Xd& gx, Eigen::Matrix2Xd& gv) {
    const bool with_v = f.provides_dfdv() && part != Part::kPositionOnly;
    if (f.provides_jacobian_products()) {
      f.add_jacobian_products(view, w.data(), gx.data(), with_v ? gv.data() : nullptr);
      return;
    }
    TransposedProduct px{w.data(), gx.data()}, pv{w.data(), gv.data()};
    const pinsim_triplet_sink sx = px.sink(), sv = pv.sink();
    f.add_jacobians(view, &sx, with_v ? &sv : nullptr);
  }

  /// gp += (df/dtheta)^T w over the entries of `part`'s forces (skip_fused: but those of the
  /// forces whose products gave them).
  void param_products(Part part, const State& s, const Eigen::Matrix2Xd& w, Eigen::VectorXd& gp,
                      bool skip_fused) {
    if (entries_.empty()) return;
    const pinsim_state_view view = s.view();
    Eigen::Matrix2Xd& fp = fp_;
    Eigen::Matrix2Xd& fm = fm_;
    for (const Entry& e : entries_) {
      if (!in_part(*sim_.forces()[e.force], part)) continue;
      if (skip_fused && fused_slots_[e.force] > 0) continue;  // vjp_with_params made it
      fp.setZero(2, s.x.cols());
      if (e.dparam >= 0) {  // the plugin's own derivative
        sim_.forces()[e.force]->add_dforce_dparam(view, static_cast<uint32_t>(e.dparam),
                                                  e.component, fp.data());
        ++dparam_evals_;
        gp[e.slot] += w.cwiseProduct(fp).sum();
        continue;
      }
      fm.setZero(2, s.x.cols());
      e.plus->add_force(view, fp.data());
      if (e.minus) {
        e.minus->add_force(view, fm.data());
      } else {
        sim_.forces()[e.force]->add_force(view, fm.data());
      }
      extra_evals_ += 2;
      gp[e.slot] += (w.cwiseProduct(fp - fm)).sum() / e.denominator;
    }
  }

  /// One force instance moved in one parameter component; `minus` null: the force itself
  /// (a one-sided difference).
  struct Entry {
    Eigen::Index slot = 0;
    std::size_t wrt = 0;  ///< the resolved value
    std::size_t force = 0;
    std::unique_ptr<ForceInstance> plus, minus;
    double denominator = 1.0;
    int64_t dparam = -1;  ///< the plugin's parameter index when it gives the derivative
    uint32_t component = 0;
    uint32_t fused_slot = 0;  ///< its slot in the force's add_adjoint_products gp
  };

  /// A force whose every differentiated value is a parameter its plugin differentiates, and
  /// which gives those derivatives' products with its Jacobians' (ABI 4.5), makes one call a
  /// product (vjp_with_params); fused_slots_ stays empty when no force does.
  void plan_fused_products() {
    std::vector<uint32_t> fused(sim_.forces().size(), 0);
    bool any = false;
    for (std::size_t i = 0; i < fused.size(); ++i) {
      const ForceInstance& f = *sim_.forces()[i];
      if (!f.provides_adjoint_products()) continue;
      bool taken = false, from_plugin = true;
      for (const Entry& e : entries_)
        if (e.force == i) {
          taken = true;
          from_plugin = from_plugin && e.dparam >= 0;
        }
      if (!taken || !from_plugin) continue;
      for (Entry& e : entries_)
        if (e.force == i)
          e.fused_slot = f.dparam_slot(static_cast<uint32_t>(e.dparam), e.component);
      fused[i] = f.dparam_slots();
      any = true;
    }
    if (any) fused_slots_ = std::move(fused);
  }

  static bool in_part(const ForceInstance& f, Part part) {
    return part == Part::kAll || f.velocity_dependent() == (part == Part::kVelocityDependent);
  }

  static nlohmann::json moved(const WrtValue& v, int c, double x) {
    if (v.value.size() == 1) return x;
    nlohmann::json a = nlohmann::json::array({v.value[0], v.value[1]});
    a[static_cast<std::size_t>(c)] = x;
    return a;
  }

  /// The parameter's instances moved by +-eps are made even when the plugin gives its
  /// derivative: implicit Euler's second-order term differences their Jacobians when another
  /// value's derivative is a difference.
  void add_parameter(const Scene& scene, PluginLoader& loader, std::size_t wrt_index,
                     const WrtValue& v, int c, double up, double down) {
    Entry e;
    e.slot = slots_;
    e.wrt = wrt_index;
    e.force = v.index;
    e.dparam = plugin_derivatives_ ? sim_.forces()[v.index]->dparam_index(v.param) : -1;
    e.component = static_cast<uint32_t>(c);
    ForceSpec spec = scene.forces[v.index];
    const State initial = scene.initial_state();
    spec.params[v.param] = moved(v, c, up);
    e.plus = create_force(scene, loader, spec, initial);
    if (down < v.value[static_cast<std::size_t>(c)] || up == v.value[static_cast<std::size_t>(c)]) {
      spec.params[v.param] = moved(v, c, down);
      e.minus = create_force(scene, loader, spec, initial);
    }
    e.denominator = up - (e.minus ? down : v.value[static_cast<std::size_t>(c)]);
    entries_.push_back(std::move(e));
  }

  /// Initial position component c of v's particles (one particle, or a body's, moved
  /// together): forces whose rest values come from the initial configuration are created
  /// again from it moved by +-eps; a force whose value at the initial state does not change
  /// (gravity, or a body's springs when the whole body moves) does not depend on it and is
  /// left out.
  void add_rest_source(const Scene& scene, PluginLoader& loader, std::size_t wrt_index,
                       const WrtValue& v, int c, double up, double down) {
    const State initial = scene.initial_state();
    const double theta = v.value[static_cast<std::size_t>(c)];
    for (std::size_t k = 0; k < scene.forces.size(); ++k) {
      State sp = initial, sm = initial;
      for (const uint32_t i : v.particles) {
        const auto col = static_cast<Eigen::Index>(i);
        // a particle the value names directly is set; a body's are moved by the same step
        sp.x(c, col) = v.kind == WrtValue::Kind::kPosition ? up : initial.x(c, col) + (up - theta);
        sm.x(c, col) =
            v.kind == WrtValue::Kind::kPosition ? down : initial.x(c, col) + (down - theta);
      }
      Entry e;
      e.slot = slots_;
      e.wrt = wrt_index;
      e.force = k;
      e.plus = create_force(scene, loader, scene.forces[k], sp);
      e.minus = create_force(scene, loader, scene.forces[k], sm);
      e.denominator = up - down;
      Eigen::Matrix2Xd fp = Eigen::Matrix2Xd::Zero(2, initial.x.cols()), fm = fp;
      e.plus->add_force(initial.view(), fp.data());
      e.minus->add_force(initial.view(), fm.data());
      if (fp == fm) continue;  // no rest value taken from this particle
      entries_.push_back(std::move(e));
    }
  }

  /// w^T (K a + D c) with force f's own Jacobians at s.
  static double jacobian_product(const ForceInstance& f, const State& s, const Eigen::Matrix2Xd& w,
                                 const Eigen::Matrix2Xd& a, const Eigen::Matrix2Xd& c) {
    Eigen::Matrix2Xd kx = Eigen::Matrix2Xd::Zero(2, w.cols()), dv = kx;
    if (f.provides_jacobian_products()) {
      f.add_jacobian_products(s.view(), w.data(), kx.data(),
                              f.provides_dfdv() ? dv.data() : nullptr);
    } else {
      TransposedProduct px{w.data(), kx.data()}, pv{w.data(), dv.data()};
      const pinsim_triplet_sink sx = px.sink(), sv = pv.sink();
      f.add_jacobians(s.view(), &sx, f.provides_dfdv() ? &sv : nullptr);
    }
    const double y = kx.cwiseProduct(a).sum() + dv.cwiseProduct(c).sum();
    return y;
  }

  void cache(const State& s) {
    const uint64_t h = s.hash();
    if (have_ && h == hash_) return;
    sim_.assemble_jacobians(s, k_, d_);
    hash_ = h;
    have_ = true;
  }

  struct SlotIndex {
    std::size_t wrt;
    int component;
    Eigen::Index slot;
  };

  Simulation& sim_;
  bool plugin_derivatives_ = true;
  Eigen::Matrix2Xd fp_, fm_;  ///< param_vjp's forces, kept between calls
  /// Per force: its add_adjoint_products' gp length when its products give its parameters'
  /// (0: separate calls); empty when no force's do.
  std::vector<uint32_t> fused_slots_;
  std::vector<double> fused_gp_;
  /// Every force gives its Jacobians (df/dv too where it may depend on v).
  bool all_exact_ = true;
  std::vector<Entry> entries_;
  std::vector<SlotIndex> slot_index_;
  Eigen::Index slots_ = 0;
  uint64_t extra_evals_ = 0;
  uint64_t dparam_evals_ = 0;
  uint64_t fused_evals_ = 0;
  Eigen::SparseMatrix<double> k_, d_;
  uint64_t hash_ = 0;
  bool have_ = false;
};

/// The forces that the replay of a step evaluated (Simulation::set_force_observer), kept in
/// storage reused from step to step.
class SeenForces {
 public:
  void clear() { count_ = 0; }
  void add(const State& s, const Eigen::Matrix2Xd& f) {
    if (count_ == seen_.size()) seen_.emplace_back();
    Seen& e = seen_[count_++];
    e.t = s.t;
    e.x = s.x;
    e.v = s.v;
    e.f = f;
  }
  /// f = the force the replay evaluated at (t, x, v), bit for bit; false if it did not.
  bool find(double t, const Eigen::Matrix2Xd& x, const Eigen::Matrix2Xd& v,
            Eigen::Matrix2Xd& f) const {
    for (std::size_t k = 0; k < count_; ++k) {
      const Seen& e = seen_[k];
      if (e.t == t && e.x.cols() == x.cols() && e.x == x && e.v == v) {
        f = e.f;
        return true;
      }
    }
    return false;
  }

 private:
  struct Seen {
    double t = 0.0;
    Eigen::Matrix2Xd x, v, f;
  };
  std::vector<Seen> seen_;
  std::size_t count_ = 0;
};

/// The velocities leaving a recorded drift: each particle's after its last change.
Eigen::Matrix2Xd drift_velocities(const DriftTape& d) {
  Eigen::Matrix2Xd v = d.v_in;
  for (const Impact& m : d.impacts) v.col(static_cast<Eigen::Index>(m.particle)) = m.v_after;
  return v;
}

/// What a step of the replay did, for its adjoint. The drift is the backend's recording
/// (`recorded`), or for a backend whose drift is x += h v without contacts it follows from
/// the state entering the step and the one leaving it (symplectic and implicit Euler: the
/// velocity leaving it; velocity Verlet: the half kick v0 + h/2 M^-1 f(x0, v0)). Velocity
/// Verlet also needs the velocities after the impact correction (correct_impacts: each
/// emitted impact k of particle i takes c_k (tau_k - h/2) (a0_i.n_k) n_k off the drift's,
/// a0 = M^-1 f(x0, v0), c_k = clamp(-(vn_after - vn_before) / vn_before, 1, 2)) and its
/// closing predictor.
void fill_tape(Scheme scheme, ForceModel& forces, const State& end, double h, bool recorded,
               const SeenForces& seen, StepTape& tape, Eigen::Matrix2Xd& f) {
  const State& start = tape.start;
  DriftTape& d = tape.drift;
  if (!recorded) {
    d.t0 = start.t;
    d.h = h;
    d.x_in = start.x;
    d.inv_mass = start.inv_mass;
    d.impacts.clear();
    d.pairs.clear();
    d.findings.clear();
  }
  tape.predicted = false;
  if (scheme != Scheme::kVelocityVerlet) {
    if (!recorded) d.v_in = end.v;
    return;
  }
  // the forces at (x0, v0) and (x1, vc): the replay's, or evaluated again (into f, storage
  // kept from step to step)
  if (!seen.find(start.t, start.x, start.v, f)) forces.force(start, f);
  if (!recorded) {
    d.v_in = start.v;
    for (Eigen::Index i = 0; i < f.cols(); ++i)
      d.v_in.col(i) += (0.5 * h * start.inv_mass[i]) * f.col(i);
  }
  tape.x1 = end.x;
  tape.vc = recorded ? drift_velocities(d) : d.v_in;
  for (const Impact& m : d.impacts) {
    const auto i = static_cast<Eigen::Index>(m.particle);
    if (!m.emitted || m.obstacle < 0 || !(start.inv_mass[i] > 0.0)) continue;
    const double vn_b = (m.v_before - m.u).dot(m.n), vn_a = (m.v_after - m.u).dot(m.n);
    if (!(vn_b < 0.0)) continue;
    const double c = std::clamp((vn_a - vn_b) / -vn_b, 1.0, 2.0);
    tape.vc.col(i) -= c * (m.tau - 0.5 * h) * (start.inv_mass[i] * f.col(i)).dot(m.n) * m.n;
  }
  if (forces.velocity_dependent()) {
    if (!seen.find(start.t, end.x, tape.vc, f)) {
      State s1 = start;
      s1.x = end.x;
      s1.v = tape.vc;
      forces.force(s1, f);
    }
    tape.vp = tape.vc;
    for (Eigen::Index i = 0; i < f.cols(); ++i)
      tape.vp.col(i) += (0.5 * h * start.inv_mass[i]) * f.col(i);
    tape.predicted = true;
  }
}

const char* kind_name(WrtValue::Kind k) {
  switch (k) {
    case WrtValue::Kind::kPosition:
      return "initial position";
    case WrtValue::Kind::kVelocity:
      return "initial velocity";
    case WrtValue::Kind::kForceParameter:
      return "force parameter";
    case WrtValue::Kind::kMaterial:
      return "obstacle material";
    case WrtValue::Kind::kBodyPosition:
      return "body position";
    case WrtValue::Kind::kBodyVelocity:
      return "body velocity";
  }
  return "";
}

const char* finding_name(Finding::Kind k) {
  switch (k) {
    case Finding::Kind::kCapHit:
      return "cap_hit";
    case Finding::Kind::kTouch:
      return "touch";
    case Finding::Kind::kGrazing:
      return "grazing";
    case Finding::Kind::kStepEnd:
      return "step_end";
    case Finding::Kind::kResting:
      return "resting";
    case Finding::Kind::kOrder:
      return "order";
  }
  return "";
}

}  // namespace

std::vector<WrtValue> resolve_wrt(const Scene& scene, const Simulation& sim,
                                  const std::vector<std::string>& paths) {
  std::vector<WrtValue> out;
  for (const std::string& p : paths) {
    const std::vector<std::string> k = split_set_path(p);
    if (k.empty()) bad_path(p, "empty path");
    if (k[0] == "particles") {
      out.push_back(particle_value(scene, p, k));
    } else if (k[0] == "forces") {
      out.push_back(force_value(scene, sim, p, k));
    } else if (k[0] == "obstacles") {
      out.push_back(material_value(scene, sim, p, k));
    } else if (k[0] == "bodies") {
      out.push_back(body_value(scene, p, k));
    } else if (scene.doc.contains(k[0])) {
      bad_path(p, "not differentiable (" + std::string(kDifferentiable) + ")");
    } else {
      bad_path(p, "the scene has no '" + k[0] + "' (" + kDifferentiable + ")");
    }
    for (std::size_t j = 0; j + 1 < out.size(); ++j)
      if (out[j].kind == out.back().kind && out[j].index == out.back().index &&
          out[j].param == out.back().param)
        bad_path(p, "names the same value as --wrt " + out[j].path);
  }
  return out;
}

GradientReport scene_gradient(const Scene& scene, PluginLoader& loader,
                              const std::vector<std::string>& wrt, const LossFactory& make_loss,
                              const GradientOptions& options) {
  Simulation sim(scene, loader, options.run);
  GradientReport r;
  r.backend = sim.backend().plugin().name();
  r.integrator = sim.integrator_name();
  r.rel_eps = options.rel_eps;
  Scheme scheme{};
  std::string why;
  if (!scheme_for(r.integrator, scheme, why)) throw InputError(scene.label + ": " + why);
  if (!(sim.backend().plugin().table->capabilities & PINSIM_CAP_DIFFERENTIABLE))
    throw InputError(scene.label + ": backend '" + r.backend +
                     "' cannot differentiate its step (it does not declare "
                     "PINSIM_CAP_DIFFERENTIABLE); differentiable backends: none, sdf");
  const std::vector<WrtValue> values = resolve_wrt(scene, sim, wrt);
  SimulationForces model(sim, scene, loader, values, options.rel_eps,
                         options.plugin_parameter_derivatives);
  const double h = scene.dt;
  const uint64_t steps = scene.steps();
  const LossContext ctx{steps, h, sim.state().size()};
  const std::unique_ptr<Loss> loss = make_loss(ctx);
  r.loss_text = loss->describe();
  r.steps = steps;

  // Forward: Simulation::step, the step of `pinsim run`, keeping a checkpoint per segment.
  const CheckpointPlan plan = CheckpointPlan::uniform(steps, options.segment);
  r.segment = plan.segment;
  r.checkpoints = plan.segments();
  r.peak_states = plan.peak_records();
  const Eigen::Index np = static_cast<Eigen::Index>(sim.state().size());
  Eigen::Matrix2Xd sx = Eigen::Matrix2Xd::Zero(2, np), sv = sx;  // scratch of the terms
  const State initial = sim.state();
  const uint64_t evals0 = sim.force_evaluations();
  auto t0 = Clock::now();
  if (loss->has_term(0)) r.loss += loss->term(0, initial, sx, sv);
  using Checkpoint = std::pair<State, uint64_t>;
  const std::vector<Checkpoint> checkpoints = forward_pass<Checkpoint, StepTape>(
      plan,
      [&] {
        return Checkpoint{sim.state(), sim.step_index()};
      },
      [&](StepTape*) { sim.step(); },
      [&](uint64_t n) {
        if (loss->has_term(n)) r.loss += loss->term(n, sim.state(), sx, sv);
      });
  r.forward_s = seconds_since(t0);
  r.forward_force_evals = sim.force_evaluations() - evals0;
  r.state_hash = sim.state().hash();
  const State final_state = sim.state();

  // Backward: each segment replayed from its checkpoint with the stages of the step, its
  // steps' adjoints in reverse.
  Adjoint a;
  a.reset(np, model.slots());
  const std::unique_ptr<Integrator> replay = make_integrator(r.integrator);
  // implicit Euler's replay hands its step's system to the adjoint step (no assembly there)
  const auto* linear = dynamic_cast<const LinearSystemStep*>(replay.get());
  const uint64_t evals1 = sim.force_evaluations(), jac1 = sim.jacobian_evaluations();
  uint64_t cur = 0;
  std::map<uint64_t, State> term_states;  // the segment's states that a loss term reads
  // A backend with contacts reports each replayed drift: its impacts and where it is not
  // differentiable.
  std::optional<DriftRecording> recording;
  if (sim.backend().can_record_drift()) recording.emplace(sim.backend());
  auto note = [&r](const Finding& f) {
    if (r.findings.size() < GradientReport::kMaxFindings) r.findings.push_back(f);
    ++r.findings_count;
  };
  // velocity Verlet's tape needs the forces at the step's start and after its drift, which
  // the replay has just evaluated
  SeenForces seen;
  Eigen::Matrix2Xd tape_forces;  // fill_tape's scratch
  if (scheme == Scheme::kVelocityVerlet)
    sim.set_force_observer([&seen](const State& s, const Eigen::Matrix2Xd& f) { seen.add(s, f); });
  t0 = Clock::now();
  backward_pass<Checkpoint, StepTape>(
      plan, checkpoints,
      [&](const Checkpoint& c) {
        sim.state() = c.first;
        cur = c.second;
        term_states.clear();
      },
      [&](StepTape* tape) {
        tape->start = sim.state();  // into the tape's own storage, reused segment after segment
        if (recording) recording->into(&tape->drift);
        seen.clear();
        replay->step(sim, h);
        ++cur;
        sim.state().t = static_cast<double>(cur) * h;
        const bool recorded = recording && recording->began();
        fill_tape(scheme, model, sim.state(), h, recorded, seen, *tape, tape_forces);
        tape->has_system =
            linear != nullptr && linear->last_system_transposed(tape->system, tape->symmetric);
        if (tape->has_system)
          r.system_blocks =
              std::max(r.system_blocks, static_cast<uint64_t>(tape->system.a.blocks()));
        if (recorded) {
          std::vector<Finding> found = tape->drift.findings;
          assess_impacts(tape->drift, found);
          for (const Finding& f : found) note(f);
          r.impacts += tape->drift.impacts.size();
        }
        if (loss->has_term(cur)) term_states[cur] = sim.state();
      },
      [&](uint64_t n, const StepTape& tape) {
        if (loss->has_term(n)) loss->term(n, term_states.at(n), a.gx, a.gv);
        adjoint_step(scheme, model, tape, h, a, r.stats);
      },
      [&](uint64_t e) {
        // Explicit steps replay to the bit; implicit Euler's iterative solve starts from the
        // previous step's solution, so its replay may differ within the solve's tolerance.
        const State& want = e == steps ? final_state : checkpoints[e / plan.segment].first;
        const double scale =
            1.0 + std::max(want.x.cwiseAbs().maxCoeff(), want.v.cwiseAbs().maxCoeff());
        const double dev = std::max((sim.state().x - want.x).cwiseAbs().maxCoeff(),
                                    (sim.state().v - want.v).cwiseAbs().maxCoeff()) /
                           scale;
        r.replay_deviation = std::max(r.replay_deviation, std::isnan(dev) ? HUGE_VAL : dev);
      });
  sim.set_force_observer({});
  adjoint_finish(model, a);
  if (loss->has_term(0)) loss->term(0, initial, a.gx, a.gv);
  recording.reset();
  r.backward_s = seconds_since(t0);
  r.backward_force_evals = sim.force_evaluations() - evals1 + model.extra_force_evals();
  r.jacobian_evals = sim.jacobian_evaluations() - jac1;
  r.dparam_evals = model.dparam_evals();
  r.fused_evals = model.fused_evals();
  if (!(r.replay_deviation <= kReplayTolerance))
    throw std::runtime_error(scene.label + ": the replay of a checkpointed segment left the " +
                             "forward run by " + num(r.replay_deviation) +
                             " (relative); the gradient would not be of this run");

  // The gradients per value.
  for (std::size_t w = 0; w < values.size(); ++w) {
    PathGradient g;
    g.wrt = values[w];
    const auto n = static_cast<Eigen::Index>(values[w].value.size());
    g.gradient.setZero(n);
    for (Eigen::Index c = 0; c < n; ++c) {
      const Eigen::Index slot = model.slot_of(w, static_cast<int>(c));
      const double gp = slot >= 0 && slot < a.gp.size() ? a.gp[slot] : 0.0;
      // component c of the state adjoint summed over the particles the value moves (one
      // particle, or a body's)
      auto over_particles = [&](const Eigen::Matrix2Xd& adj) {
        const std::vector<uint32_t>& ps = values[w].particles;
        double sum = ps.empty() ? 0.0 : adj(c, ps[0]);
        for (std::size_t j = 1; j < ps.size(); ++j) sum += adj(c, ps[j]);
        return sum;
      };
      switch (values[w].kind) {
        case WrtValue::Kind::kPosition:
        case WrtValue::Kind::kBodyPosition:
          // d L / d p = sum of d L / d x_i(0), plus the rest values' part
          g.gradient[c] = over_particles(a.gx) + gp;
          break;
        case WrtValue::Kind::kVelocity:
        case WrtValue::Kind::kBodyVelocity:
          g.gradient[c] = over_particles(a.gv);
          break;
        case WrtValue::Kind::kForceParameter:
          g.gradient[c] = gp;
          g.plugin_derivative = model.from_plugin(w);
          r.any_parameter = true;
          break;
        case WrtValue::Kind::kMaterial: {
          const MaterialGrad& m = a.material;
          const auto k = static_cast<int64_t>(values[w].index);
          const std::string& name = values[w].param;
          g.gradient[c] = MaterialGrad::at(name == "restitution" ? m.restitution
                                           : name == "friction"  ? m.friction
                                                                 : m.kick,
                                           k);
          break;
        }
      }
    }
    r.paths.push_back(std::move(g));
  }
  return r;
}

nlohmann::json GradientReport::to_json() const {
  nlohmann::json paths_json = nlohmann::json::object();
  for (const PathGradient& p : paths) {
    nlohmann::json g = nlohmann::json::array(), v = nlohmann::json::array();
    for (Eigen::Index c = 0; c < p.gradient.size(); ++c) g.push_back(p.gradient[c]);
    for (double x : p.wrt.value) v.push_back(x);
    nlohmann::json e = {{"value", v}, {"gradient", g}, {"kind", kind_name(p.wrt.kind)}};
    if (p.wrt.kind == WrtValue::Kind::kForceParameter) {
      e["parameter derivative"] = p.plugin_derivative ? "plugin" : "finite differences";
    } else if (p.wrt.kind == WrtValue::Kind::kPosition ||
               p.wrt.kind == WrtValue::Kind::kBodyPosition) {
      e["rest values"] = "finite differences";
    }
    paths_json[p.wrt.path] = e;
  }
  nlohmann::json f = nlohmann::json::array();
  for (const Finding& x : findings)
    f.push_back({{"kind", finding_name(x.kind)},
                 {"particle", x.particle},
                 {"obstacle", x.obstacle},
                 {"t", x.t},
                 {"margin", x.margin}});
  nlohmann::json out = {
      {"loss", loss},
      {"loss_description", loss_text},
      {"differentiable", findings_count == 0},
      {"findings", f},
      {"findings_count", findings_count},
      {"impacts", impacts},
      {"paths", paths_json},
      {"backend", backend},
      {"integrator", integrator},
      {"steps", steps},
      {"replay_deviation", replay_deviation},
      {"state_hash", fmt::format("{:016x}", state_hash)},
      {"checkpoints", {{"segment", segment}, {"count", checkpoints}, {"peak_states", peak_states}}},
      {"cost",
       {{"forward_s", forward_s},
        {"backward_s", backward_s},
        {"backward_over_forward", forward_s > 0.0 ? backward_s / forward_s : 0.0},
        {"forward_force_evaluations", forward_force_evals},
        {"backward_force_evaluations", backward_force_evals},
        {"backward_jacobian_evaluations", jacobian_evals},
        {"parameter_derivative_evaluations", dparam_evals},
        {"fused_product_evaluations", fused_evals},
        {"transposed_solves", stats.solves},
        {"worst_solve_residual", stats.worst_residual}}},
  };
  if (any_parameter) {
    bool plugin = false, differences = false;
    for (const PathGradient& p : paths)
      if (p.wrt.kind == WrtValue::Kind::kForceParameter)
        (p.plugin_derivative ? plugin : differences) = true;
    nlohmann::json d = {{"method", plugin && differences ? "plugin and finite differences"
                                   : plugin              ? "plugin"
                                                         : "finite differences"}};
    if (plugin)
      d["plugin"] =
          "the force plugin's add_dforce_dparam: d f / d theta at the step's state (check-plugin "
          "compares it with central differences), or its add_adjoint_products: w . d f / d "
          "theta with the Jacobian products in one pass (check-plugin compares the two)";
    if (differences) {
      d["relative_step"] = rel_eps;
      d["formula"] =
          "(f(theta + eps) - f(theta - eps)) / (2 eps), eps = relative_step max(|theta|, 1)";
    }
    out["parameter derivative"] = d;
  }
  return out;
}

}  // namespace pinsim::grad
