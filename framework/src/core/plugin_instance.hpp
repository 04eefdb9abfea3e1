// Live plugin instances: a created object plus the library that must outlive it.
#pragma once

#include <memory>
#include <nlohmann/json.hpp>
#include <pinsim/state.hpp>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/plugin_loader.hpp"

namespace pinsim {

/// A plugin call failed (it returned an error code); the message names the plugin.
class PluginError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Arguments for creating an instance.
struct InstanceArgs {
  nlohmann::json params;           ///< validated, defaults filled
  nlohmann::json scene;            ///< backends only
  std::vector<uint32_t> elements;  ///< forces only
  std::string context;             ///< "scene.json: forces[2]"
};

class ForceInstance {
 public:
  ForceInstance(std::shared_ptr<const LoadedPlugin> plugin, const State& initial,
                InstanceArgs args);
  ~ForceInstance();
  ForceInstance(const ForceInstance&) = delete;
  ForceInstance& operator=(const ForceInstance&) = delete;

  void add_force(const pinsim_state_view& s, double* f) const;
  bool has_energy() const { return plugin_->table->force.energy != nullptr; }
  double energy(const pinsim_state_view& s) const;
  bool has_jacobians() const { return plugin_->table->force.add_jacobians != nullptr; }
  /// Declared capabilities (PINSIM_CAP_*), read through these rather than the table.
  bool declares_energy() const { return has_cap(PINSIM_CAP_ENERGY); }
  bool provides_dfdx() const { return has_jacobians() && has_cap(PINSIM_CAP_DFDX); }
  bool provides_dfdv() const { return has_jacobians() && has_cap(PINSIM_CAP_DFDV); }
  bool dissipative() const { return has_cap(PINSIM_CAP_DISSIPATIVE); }
  /// Its instances may run at the same time on two threads (PINSIM_CAP_CONCURRENT).
  bool concurrent() const { return has_cap(PINSIM_CAP_CONCURRENT); }
  /// May depend on velocity: damping, or no energy declared (then nothing rules it out).
  bool velocity_dependent() const { return dissipative() || !declares_energy(); }
  void add_jacobians(const pinsim_state_view& s, const pinsim_triplet_sink* dfdx,
                     const pinsim_triplet_sink* dfdv) const;
  /// The force is a sum of soft constraints it reports (PINSIM_CAP_CONSTRAINTS, ABI 4.2).
  bool provides_constraints() const {
    return has_cap(PINSIM_CAP_CONSTRAINTS) && plugin_->table->constraint_set != nullptr &&
           plugin_->table->constraints != nullptr;
  }
  /// The plugin's constraint set, unchecked (core/constraints.hpp checks it). Throws
  /// PluginError.
  pinsim_constraint_set constraint_set() const;
  /// C and dC/dp of the constraints `which` at positions x (pinsim_plugin.constraints). May
  /// run on several threads at once (an error buffer per call). Throws PluginError.
  void constraints(const double* x, const uint64_t* which, uint64_t count, double* c,
                   double* dc) const;
  /// The plugin gives the force's derivative in its parameter `name` (ABI 4.4,
  /// PINSIM_CAP_DPARAM with the parameter flagged PINSIM_PARAM_DIFFERENTIABLE); its index
  /// in the plugin's parameter table, or -1.
  int64_t dparam_index(const std::string& name) const;
  /// The plugin gives (df/dx)^T w and (df/dv)^T w itself (ABI 4.4,
  /// PINSIM_CAP_JACOBIAN_PRODUCTS).
  bool provides_jacobian_products() const {
    return plugin_->table->add_jacobian_products != nullptr &&
           has_cap(PINSIM_CAP_JACOBIAN_PRODUCTS) && provides_dfdx();
  }
  /// gx += (df/dx)^T w, gv += (df/dv)^T w (gv may be null) at s. Throws PluginError.
  void add_jacobian_products(const pinsim_state_view& s, const double* w, double* gx,
                             double* gv) const;
  /// df += d f / d (component `component` of parameter `param`) at s
  /// (pinsim_plugin.add_dforce_dparam). Throws PluginError.
  void add_dforce_dparam(const pinsim_state_view& s, uint32_t param, uint32_t component,
                         double* df) const;
  /// The plugin gives its Jacobian products and its parameter derivatives' products in one
  /// call (ABI 4.5, PINSIM_CAP_ADJOINT_PRODUCTS).
  bool provides_adjoint_products() const {
    return plugin_->table->add_adjoint_products != nullptr &&
           has_cap(PINSIM_CAP_ADJOINT_PRODUCTS) && provides_jacobian_products();
  }
  /// Where component `component` of differentiable parameter `param` (an index from
  /// dparam_index) sits in add_adjoint_products' gp, and (dparam_slots) gp's length: the
  /// flagged parameters' components in the table's order.
  uint32_t dparam_slot(uint32_t param, uint32_t component) const;
  uint32_t dparam_slots() const;
  /// add_jacobian_products at s and gp[j] += w . d f / d theta_j for every differentiable
  /// component (pinsim_plugin.add_adjoint_products). Throws PluginError.
  void add_adjoint_products(const pinsim_state_view& s, const double* w, double* gx, double* gv,
                            double* gp) const;

  const LoadedPlugin& plugin() const { return *plugin_; }
  const std::string& context() const { return context_; }
  const std::vector<uint32_t>& elements() const { return elements_; }

 private:
  [[noreturn]] void fail(const char* what) const;
  bool has_cap(uint32_t cap) const { return (plugin_->table->capabilities & cap) != 0; }
  std::shared_ptr<const LoadedPlugin> plugin_;
  void* self_ = nullptr;
  std::string context_;
  std::vector<uint32_t> elements_;
  mutable std::vector<char> err_;
};

/// What a backend's outline() reported (PINSIM_CAP_OUTLINES), copied out of the plugin.
struct OutlineReport {
  struct Obstacle {
    int64_t index = -1;  ///< into the scene's "obstacles"
    std::string id;
    pinsim_bounds bounds{};                           ///< its boundary's bounds at the state's time
    pinsim_bounds sweep{};                            ///< ... over every pose its motion can take
    std::vector<std::vector<Eigen::Vector2d>> rings;  ///< closed polylines, scene units
  };
  std::vector<Obstacle> obstacles;
  pinsim_bounds bounds{};  ///< the whole set's bounds at the state's time
  pinsim_bounds sweep{};   ///< ... over every pose
};

class BackendInstance {
 public:
  BackendInstance(std::shared_ptr<const LoadedPlugin> plugin, const State& initial,
                  InstanceArgs args);
  ~BackendInstance();
  BackendInstance(const BackendInstance&) = delete;
  BackendInstance& operator=(const BackendInstance&) = delete;

  void advance(State& s, double dt, const pinsim_event_sink* events);
  bool has_distance() const { return plugin_->table->backend.distance != nullptr; }
  double distance(double x, double y, double t, int64_t* obstacle) const;
  /// True if the backend takes live input events (PINSIM_CAP_INPUTS).
  bool has_input() const {
    return plugin_->table->backend.input != nullptr &&
           (plugin_->table->capabilities & PINSIM_CAP_INPUTS) != 0;
  }
  /// Input `name` pressed or released at time t, between steps. Throws PluginError if the
  /// backend has no input() or refuses the event (an unknown name).
  void input(const std::string& name, bool pressed, double t);
  /// True if the backend reports its obstacles' outlines (PINSIM_CAP_OUTLINES).
  bool has_outline() const {
    return plugin_->table->backend.outline != nullptr &&
           (plugin_->table->capabilities & PINSIM_CAP_OUTLINES) != 0;
  }
  /// The obstacles' outlines and bounds for state s, within `tolerance` (scene units; <= 0:
  /// the backend's default). Throws PluginError if the backend has no outline() or fails.
  OutlineReport outline(const State& s, double tolerance) const;
  const LoadedPlugin& plugin() const { return *plugin_; }
  /// True if the backend reports its drifts for the adjoint of a run (ABI 4.3 record_drift,
  /// with PINSIM_CAP_DIFFERENTIABLE).
  bool can_record_drift() const {
    return plugin_->table->record_drift != nullptr &&
           (plugin_->table->capabilities & PINSIM_CAP_DIFFERENTIABLE) != 0;
  }
  /// Every advance() from now on reports its drift to `sink` (null: stop). Throws
  /// PluginError if the backend cannot or fails.
  void record_drift(const pinsim_drift_sink* sink);

 private:
  [[noreturn]] void fail(const char* what) const;
  std::shared_ptr<const LoadedPlugin> plugin_;
  void* self_ = nullptr;
  std::string context_;
  mutable std::vector<char> err_;
};

}  // namespace pinsim
