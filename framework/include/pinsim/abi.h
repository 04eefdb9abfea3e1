/* pinsim plugin ABI: the C boundary between the host and a plugin library.
 *
 * A plugin library exports exactly one function, `pinsim_plugin_entry`, returning a
 * pointer to a constant `pinsim_plugin` table. Everything that crosses is plain C:
 * numbers, `const char*`, plain arrays and function pointers. Errors are return codes
 * (0 = success) plus a message written into a caller-owned `pinsim_error` buffer.
 *
 * Arrays of positions, velocities and forces are 2xN column-major doubles:
 * x0 y0 x1 y1 ... . Degrees of freedom are numbered dof = 2*particle + component.
 *
 * Authors normally do not write this table by hand: `pinsim/plugin.hpp` generates it
 * from an ordinary C++ class.
 *
 * Versions are major.minor (PINSIM_ABI_MAJOR, PINSIM_ABI_MINOR); a table states the
 * version it was built against in abi_version (the major) and abi_minor, and its length in
 * struct_size (sizeof(pinsim_plugin) where it was built).
 * - A minor version only adds: entries at the end of pinsim_plugin, members at the end of
 *   a struct the host fills and hands to the plugin (pinsim_create_args, the state views,
 *   the sinks, pinsim_error), capability flags and conventions. Every added table entry is
 *   optional: the host reads it only when struct_size says the table holds it
 *   (PINSIM_TABLE_HAS) and the table's minor is at least the one that added it, and takes
 *   it as absent (NULL or 0) otherwise. So the host loads a plugin built against any minor
 *   of its major up to its own, unchanged and unrebuilt. It refuses a plugin built against
 *   a newer minor than its own (such a plugin may read members of the host's structs that
 *   this host does not fill), and a table shorter than its minor's layout.
 * - A major version is any other change: a member moved, removed or retyped, or a struct
 *   the plugin fills for the host made longer (pinsim_param, pinsim_event, pinsim_outline,
 *   and pinsim_force_api and pinsim_backend_api, which sit inside the table before its
 *   end). The host refuses every major but its own, and a table shorter than the smallest
 *   of its major (PINSIM_ABI_MIN_TABLE_SIZE), naming the plugin file and both versions.
 */
#ifndef PINSIM_ABI_H
#define PINSIM_ABI_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/** Major version: changes with every incompatible change (see the top of this file). */
#define PINSIM_ABI_MAJOR 4u
/** Minor version: counts the compatible additions within the major. */
#define PINSIM_ABI_MINOR 5u
/** The value of pinsim_plugin.abi_version: the major version. */
#define PINSIM_ABI_VERSION PINSIM_ABI_MAJOR

/** Force arity of a plugin whose elements have variable length: each element is a whole
 *  body or a closed ring (all of a blob's boundary particles in order), not a fixed-size
 *  stencil. Such elements cross in `pinsim_create_args.elements` one after another, each
 *  as its length L followed by its L particle indices (length-prefixed); `n_elements`
 *  counts elements. The SDK's create() refuses, with a message saying so, a host that
 *  passes such a plugin elements of a fixed arity. */
#define PINSIM_ARITY_VARIABLE 0u

/** Name of the one exported symbol of every plugin library. */
#define PINSIM_ENTRY_SYMBOL "pinsim_plugin_entry"

typedef enum pinsim_kind { PINSIM_KIND_FORCE = 1, PINSIM_KIND_BACKEND = 2 } pinsim_kind;

/** Capability flags (pinsim_plugin.capabilities). */
enum {
  PINSIM_CAP_ENERGY = 1u << 0,      /**< force: energy() is provided (conservative part) */
  PINSIM_CAP_DFDX = 1u << 1,        /**< force: df/dx Jacobian is provided */
  PINSIM_CAP_DFDV = 1u << 2,        /**< force: df/dv Jacobian is provided */
  PINSIM_CAP_INTERNAL = 1u << 3,    /**< force: internal, so sum f = 0 and sum x*f = 0 */
  PINSIM_CAP_DISSIPATIVE = 1u << 4, /**< force: has a velocity-dependent damping part */
  /** force: two instances may be called at the same time from two threads (they share no
   *  mutable state: no static or global scratch). The host then may compute two such
   *  forces' Jacobians at once; a host that does not know the bit ignores it. */
  PINSIM_CAP_CONCURRENT = 1u << 5,
  /** force (4.2): constraint_set() and constraints() are provided: the force is a sum of soft
   *  constraints (pinsim_constraint_set) */
  PINSIM_CAP_CONSTRAINTS = 1u << 6,
  /** force (4.4): add_dforce_dparam() is provided: the force's derivatives in its parameters
   *  flagged PINSIM_PARAM_DIFFERENTIABLE (at least one) */
  PINSIM_CAP_DPARAM = 1u << 7,
  PINSIM_CAP_DISTANCE = 1u << 8,         /**< backend: distance() is provided */
  PINSIM_CAP_PARTICLE_CONTACT = 1u << 9, /**< backend: can resolve particle-particle contacts */
  PINSIM_CAP_INPUTS = 1u << 10,          /**< backend: input() is provided */
  PINSIM_CAP_OUTLINES = 1u << 11,        /**< backend: outline() is provided */
  /** backend (4.2): its advance() is differentiable as the host's adjoint of a run assumes: a
   *  drift without contacts is x += dt v for particles with inv_mass > 0 (pinned ones stay),
   *  and the backend reports no contact it did not make. `pinsim grad` refuses a backend
   *  without it; a host that does not know the bit ignores it. */
  PINSIM_CAP_DIFFERENTIABLE = 1u << 12,
  /** force (4.4): add_jacobian_products() is provided (with PINSIM_CAP_DFDX, and
   *  PINSIM_CAP_DFDV if the force may depend on velocity) */
  PINSIM_CAP_JACOBIAN_PRODUCTS = 1u << 13,
  /** force (4.5): add_adjoint_products() is provided (with PINSIM_CAP_JACOBIAN_PRODUCTS and
   *  PINSIM_CAP_DPARAM) */
  PINSIM_CAP_ADJOINT_PRODUCTS = 1u << 14
};

/** Declared parameter types. */
typedef enum pinsim_param_type {
  PINSIM_PARAM_REAL = 1,   /**< a double */
  PINSIM_PARAM_INT = 2,    /**< an integer (stored in a double, must be integral) */
  PINSIM_PARAM_BOOL = 3,   /**< true/false */
  PINSIM_PARAM_STRING = 4, /**< a string; if `choices` is set, one of "a|b|c" */
  PINSIM_PARAM_VEC2 = 5    /**< a 2-vector [x, y]; min/max bound each component */
} pinsim_param_type;

/** Parameter flags. */
enum {
  PINSIM_PARAM_REQUIRED = 1u << 0,      /**< the scene must give a value */
  PINSIM_PARAM_MIN_EXCLUSIVE = 1u << 1, /**< value must be > min rather than >= min */
  PINSIM_PARAM_MAX_EXCLUSIVE = 1u << 2, /**< value must be < max rather than <= max */
  /** 4.4, forces with PINSIM_CAP_DPARAM: add_dforce_dparam() gives the force's derivative in
   *  this parameter (REAL or VEC2 only) */
  PINSIM_PARAM_DIFFERENTIABLE = 1u << 3
};

/** One declared parameter. Unbounded ranges use +-HUGE_VAL. */
typedef struct pinsim_param {
  const char* name;           /**< key in the scene's "params" object */
  uint32_t type;              /**< pinsim_param_type */
  uint32_t flags;             /**< PINSIM_PARAM_* flags */
  double default_value[2];    /**< default (REAL/INT/BOOL use [0]; VEC2 uses both) */
  const char* default_string; /**< default for STRING, may be NULL */
  const char* choices;        /**< for STRING: allowed values "a|b|c", or NULL for any */
  double min;                 /**< lower bound (see flags) */
  double max;                 /**< upper bound (see flags) */
  const char* units;          /**< e.g. "N/m", "1" for dimensionless */
  const char* doc;            /**< one line */
} pinsim_param;

/** Error buffer owned by the caller. Plugins write a NUL-terminated message. */
typedef struct pinsim_error {
  char* message;
  uint32_t capacity;
} pinsim_error;

/** Read-only view of the particle state. */
typedef struct pinsim_state_view {
  uint64_t n;             /**< number of particles */
  double t;               /**< time, s */
  const double* x;        /**< positions, 2n */
  const double* v;        /**< velocities, 2n */
  const double* inv_mass; /**< 1/m per particle, 0 = pinned (kinematic) */
  const double* radius;   /**< radius per particle, scene units */
} pinsim_state_view;

/** Mutable positions and velocities, for a backend's advance(). */
typedef struct pinsim_state_mut {
  uint64_t n;
  double t; /**< time at the start of the step */
  double* x;
  double* v;
  const double* inv_mass;
  const double* radius;
} pinsim_state_mut;

/** Sparse matrix sink: the plugin adds value at (row, col), rows/cols are dofs.
 *  add_blocks (may be NULL: then use add) adds `count` 2x2 blocks d f_i / d x_j in one call:
 *  block k is at particles i = particles[2k], j = particles[2k + 1] (dofs 2i, 2i+1 by
 *  2j, 2j+1) with values[4k .. 4k+3] = its entries column-major (d f_ix/d x_jx,
 *  d f_iy/d x_jx, d f_ix/d x_jy, d f_iy/d x_jy). Equivalent to the four add() calls of each
 *  block, row by row ((2i,2j), (2i,2j+1), (2i+1,2j), (2i+1,2j+1)), block after block. */
typedef struct pinsim_triplet_sink {
  void* context;
  void (*add)(void* context, uint32_t row, uint32_t col, double value);
  void (*add_blocks)(void* context, const uint32_t* particles, const double* values,
                     uint64_t count);
} pinsim_triplet_sink;

/** One contact, reported by a backend. obstacle is the index into the scene's
 *  "obstacles" array, or -1 for a particle-particle contact (then `other` is set). */
typedef struct pinsim_event {
  double t;         /**< time of impact, s */
  int64_t particle; /**< particle index */
  int64_t obstacle; /**< obstacle index, or -1 */
  int64_t other;    /**< other particle for particle-particle contacts, else -1 */
  double point[2];  /**< contact point */
  double normal[2]; /**< unit normal, pointing from the obstacle to the particle */
  double vn_before; /**< relative normal velocity before the impulse (< 0: approaching) */
  double vn_after;  /**< relative normal velocity after the impulse */
} pinsim_event;

/** Where a backend's advance() puts its events, in order, each copied by emit before it
 *  returns. A backend calls emit only from the thread that called advance(), but it may do so
 *  while its other threads are still writing the state: a sink records the event and reads
 *  nothing of the state. */
typedef struct pinsim_event_sink {
  void* context;
  void (*emit)(void* context, const pinsim_event* event);
} pinsim_event_sink;

/** An axis-aligned rectangle, scene units; empty when x0 > x1 (none: +inf, +inf, -inf, -inf). */
typedef struct pinsim_bounds {
  double x0, y0, x1, y1;
} pinsim_bounds;

/** One obstacle's outline, reported by a backend's outline(). Valid during the emit call. */
typedef struct pinsim_outline {
  int64_t obstacle;           /**< index into the scene's "obstacles" array */
  const char* id;             /**< the obstacle's id */
  pinsim_bounds bounds;       /**< bounds of its boundary at the state's time */
  pinsim_bounds sweep;        /**< bounds of its boundary over every pose its motion can take
                                   (= bounds for a static obstacle) */
  uint32_t n_rings;           /**< closed polylines of its boundary */
  const uint32_t* ring_sizes; /**< points in each ring (the first point is not repeated) */
  const double* points;       /**< every ring's points one after another, x0 y0 x1 y1 ..., scene
                                   units; a ring runs with the solid on its left */
} pinsim_outline;

typedef struct pinsim_outline_sink {
  void* context;
  void (*emit)(void* context, const pinsim_outline* outline);
} pinsim_outline_sink;

/** What create() receives. */
typedef struct pinsim_create_args {
  const char* params_json; /**< validated parameters, defaults filled, a JSON object */
  const char* scene_json;  /**< backends: {"obstacles":[...],"inputs":[...],...}; forces: NULL */
  const pinsim_state_view* initial; /**< the initial state (rest values default to it) */
  /** n_elements * arity particle indices; for PINSIM_ARITY_VARIABLE, per element its
   *  length L then L indices */
  const uint32_t* elements;
  uint64_t n_elements;
  uint32_t arity;      /**< equals the plugin's declared arity */
  const char* context; /**< where this instance comes from, for messages */
} pinsim_create_args;

typedef struct pinsim_force_api {
  /** f += force(state). f has 2n entries. */
  int (*add_force)(void* self, const pinsim_state_view* s, double* f, pinsim_error* err);
  /** *energy = potential energy; NULL unless PINSIM_CAP_ENERGY. */
  int (*energy)(void* self, const pinsim_state_view* s, double* energy, pinsim_error* err);
  /** Adds df/dx and df/dv entries; either sink may be NULL; NULL unless DFDX or DFDV. */
  int (*add_jacobians)(void* self, const pinsim_state_view* s, const pinsim_triplet_sink* dfdx,
                       const pinsim_triplet_sink* dfdv, pinsim_error* err);
} pinsim_force_api;

/* The backend contract. A backend owns the position update (the drift): the host's
 * integrator changes the velocities (forces, kicks, impact corrections), the backend moves
 * the particles along them and resolves every contact on the way.
 *
 * advance(self, s, dt, events, err) moves the state over [s->t, s->t + dt]:
 * - Calls: once per step, the steps in time order, on the simulation's state, with the
 *   velocities the integrator drifts with (symplectic Euler: after its kick
 *   v += dt M^-1 f); input() calls come between steps. s->t is the step's start time; the
 *   host advances the time.
 * - May: move every particle with inv_mass > 0 along its velocity, and change such a
 *   particle's velocity by contact impulses, each reported as one event. A particle with
 *   no contact in the step ends at x + dt v with v unchanged (the grader compares free
 *   flight with its closed form).
 * - May not: change a velocity without reporting the impulse (no forces, gravity or
 *   damping: those are force plugins); move or change a pinned particle (inv_mass 0); change
 *   n, inv_mass or radius; keep a pointer into s or events after it returns; call the host
 *   other than through events->emit during the call.
 * - Events (pinsim_event), all members finite: t is the time of the impact, in
 *   [s->t, s->t + dt] (an integrator's impact correction moves the velocity by
 *   (t - s->t) times the normal acceleration: an error in t is an error in v); normal is a
 *   unit vector from the obstacle to the particle; vn_before is the relative normal
 *   velocity (v - u).normal just before the impulse, u the velocity of the obstacle's
 *   surface there, and vn_after the same just after, so vn_after - vn_before is the
 *   impulse's change of the normal velocity. Impulses only while approaching
 *   (vn_before < 0). The events of one call come in an order fixed by the state (the sdf
 *   backend: by particle, each particle's in time order); the host keeps that order.
 * - Deterministic: the same create() arguments, input() calls and advance() arguments
 *   give the same bits in x, v and the events, on every run and for every thread count
 *   (`pinsim run --threads N`). No clocks, no random numbers but from a seed parameter, no
 *   dependence on addresses or on which thread finishes first; sums in a fixed order.
 *   Threads inside advance() are the backend's own affair under that rule; the host never
 *   calls one instance from two threads at once. Compile with -ffp-contract=off, as the
 *   host is (pinsim_add_plugin does).
 * - Errors: a nonzero return with a message stops the run at that step, exit 1, naming the
 *   backend. Refuse before moving anything where possible (the sdf backend checks every
 *   velocity first), so that the state reported is the one the step started from.
 * distance() and outline() only read; input() changes the obstacles' motion from time t on,
 * never the particles. The grader checks advance() against this contract on a submitted
 * backend: docs/grading.md, backend checks, gives the checks and their tolerances. */
typedef struct pinsim_backend_api {
  /** Move x along v over [t, t+dt], resolving every contact on the way (the contract
   *  above). */
  int (*advance)(void* self, pinsim_state_mut* s, double dt, const pinsim_event_sink* events,
                 pinsim_error* err);
  /** Signed distance from p to the obstacles at time t; NULL unless PINSIM_CAP_DISTANCE.
   *  *obstacle receives the nearest obstacle's index (may be NULL). */
  int (*distance)(void* self, const double* p, double t, double* distance, int64_t* obstacle,
                  pinsim_error* err);
  /** A live input event between steps (a flipper key pressed or released): input `name`
   *  changes to `pressed` (1) or released (0) at time t, s, as if the scene's "inputs" list
   *  had held {"t", "input", "action"} from the start. Calls come in time order, with t at
   *  or after every earlier event and equal to the state time of the next advance(); an
   *  unknown name is an error naming it. NULL unless PINSIM_CAP_INPUTS. */
  int (*input)(void* self, const char* name, int pressed, double t, pinsim_error* err);
  /** The obstacles' outlines for the state s (its time; its particles may size the part of
   *  an unbounded obstacle, a half-plane, that is outlined): each obstacle once, in scene
   *  order, to `sink`, as closed polylines within `tolerance` of the exact boundary (scene
   *  units; <= 0: the backend's default, documented in its README); *bounds and *sweep
   *  (either may be NULL) receive the bounds of the whole set at s.t and over every pose.
   *  NULL unless PINSIM_CAP_OUTLINES. */
  int (*outline)(void* self, const pinsim_state_view* s, double tolerance,
                 const pinsim_outline_sink* sink, pinsim_bounds* bounds, pinsim_bounds* sweep,
                 pinsim_error* err);
} pinsim_backend_api;

/** A force written as soft constraints (4.2; seed lecture, "Generalized spring model"): with
 *  C_e(x) the constraint of element e and J_e = dC_e/dx its gradient,
 *    E = sum_e ks_e/2 C_e^2 + const,   f = -sum_e J_e^T (ks_e C_e + kd_e J_e v),
 *  so the plugin's energy() (if any) and add_force() agree with it. A host may use the
 *  constraints in place of add_force (XPBD: compliance 1/ks_e), so both must describe the same
 *  force. Filled by constraint_set(); its arrays belong to the instance and stay valid and
 *  unchanged while it lives. */
typedef struct pinsim_constraint_set {
  uint64_t count; /**< number of constraints (elements) */
  uint32_t arity; /**< particles per constraint, or PINSIM_ARITY_VARIABLE */
  /** the constraints' particles: count * arity indices, or for PINSIM_ARITY_VARIABLE per
   *  constraint its length L (>= 1) then its L indices, as pinsim_create_args.elements */
  const uint32_t* particles;
  const double* ks; /**< count stiffnesses, >= 0 (0: the constraint exerts no force); J/C^2 */
  const double* kd; /**< count dampings, >= 0, on dC/dt; J s/C^2 */
} pinsim_constraint_set;

/* 4.3: what a differentiable backend reports of each drift (one advance() call) while the
 * host records (record_drift), so that the host's adjoint of a run can differentiate it
 * (docs/gradients.md). All times are into the drift, s; vectors are (x, y); 2x2 matrices
 * column-major. */

/** How an impact's time is determined (pinsim_drift_impact.kind). */
enum {
  /** the path reached the contact offset: phi(p, t0 + tau) = offset along the straight path
   *  since the previous velocity change (the time of impact) */
  PINSIM_IMPACT_TOI = 0,
  /** an impulse where the particle already was, inside the contact band (a persistent or
   *  resting contact): tau is the march's time, not a root of phi */
  PINSIM_IMPACT_IN_BAND = 1,
  /** the velocity change of a particle-particle contact (pinsim_drift_pair `pair`, `side`) */
  PINSIM_IMPACT_CHANGE = 2
};
/** pinsim_drift_impact.flags */
enum {
  PINSIM_IMPACT_RESTING = 1u << 0, /**< slower than the rest speed: restitution 0, no kick */
  PINSIM_IMPACT_EMITTED = 1u << 1  /**< reported as a contact event */
};

/** One velocity change of one particle. Per drift, a particle's changes come in time order,
 *  the particles in increasing order. */
typedef struct pinsim_drift_impact {
  uint32_t kind;      /**< PINSIM_IMPACT_* */
  uint32_t flags;     /**< PINSIM_IMPACT_RESTING, PINSIM_IMPACT_EMITTED */
  int64_t particle;   /**< its index */
  int64_t obstacle;   /**< index into the scene's "obstacles", or -1 (CHANGE) */
  int64_t pair;       /**< CHANGE: index of the pair hit in this drift, else -1 */
  int64_t side;       /**< CHANGE: 0 the hit's particle i, 1 its particle j */
  double tau;         /**< time of the change, s into the drift */
  double p[2];        /**< the centre there (before a push back to the offset) */
  double v_before[2]; /**< velocity before the change */
  double v_after[2];  /**< velocity after it */
  double n[2];        /**< unit normal grad phi at (p, t0 + tau) */
  double n_p[4];      /**< d n / d p (the SDF's Hessian), 1/length */
  double n_t[2];      /**< d n / d t at fixed p, 1/s */
  double phi, phi_t;  /**< the centre's signed distance, and d phi / d t at fixed p */
  double offset;      /**< radius + the backend's contact offset: the level of a TOI */
  double u[2];        /**< the obstacle's velocity at the contact point p - phi n */
  double u_p[4];      /**< d u / d q there, 1/s */
  double u_t[2];      /**< d u / d t there */
  double restitution; /**< the obstacle's material */
  double friction;    /**< Coulomb coefficient */
  double kick;        /**< speed added along the normal */
} pinsim_drift_impact;

/** One particle-particle contact: discs i and j on the tracks x(tau) = xr + vc (tau - tr),
 *  hit at the root tau of |x_i - x_j| = radius_sum (touching: already overlapping at
 *  max(tr_i, tr_j), and tau is that), impulse -(1 + e) vn / (w_i + w_j) along the normal. */
typedef struct pinsim_drift_pair {
  int64_t i, j;
  double tau;
  double xr_i[2], vc_i[2], tr_i;
  double xr_j[2], vc_j[2], tr_j;
  double radius_sum, w_i, w_j, restitution;
  uint32_t touching;
} pinsim_drift_pair;

/** Where the drift was not differentiable or came close to it (pinsim_drift_finding.kind). */
enum {
  PINSIM_FINDING_CAP_HIT = 0,  /**< a march ran out of collisions or iterations */
  PINSIM_FINDING_TOUCH = 1,    /**< the path touched the contact band without approaching */
  PINSIM_FINDING_GRAZING = 2,  /**< an impulse with almost no normal speed */
  PINSIM_FINDING_STEP_END = 3, /**< a time of impact at the start or end of the drift */
  PINSIM_FINDING_RESTING = 4,  /**< a resting contact */
  PINSIM_FINDING_ORDER = 5     /**< particle-particle changes out of time order */
};
typedef struct pinsim_drift_finding {
  uint32_t kind;
  int64_t particle;
  int64_t obstacle; /**< or -1 */
  double t;         /**< absolute time, s */
  double margin;    /**< e.g. the normal speed of a grazing impact */
} pinsim_drift_finding;

/** Receives one drift: begin() with the state entering advance() first, then the pair hits
 *  (in the order the backend handled them), the impacts and the findings. */
typedef struct pinsim_drift_sink {
  void* context;
  void (*begin)(void* context, const pinsim_state_view* entering, double dt);
  void (*pair)(void* context, const pinsim_drift_pair* hit);
  void (*impact)(void* context, const pinsim_drift_impact* impact);
  void (*finding)(void* context, const pinsim_drift_finding* finding);
} pinsim_drift_sink;

/** The table a plugin exports. Check abi_version and struct_size before anything else
 *  (the versions at the top of this file). */
typedef struct pinsim_plugin {
  uint32_t abi_version; /**< PINSIM_ABI_VERSION the plugin was built with */
  uint32_t struct_size; /**< sizeof(pinsim_plugin) the plugin was built with */
  uint32_t kind;        /**< pinsim_kind */
  uint32_t arity;       /**< forces: particles per element (1 = per particle, 2 = pair, 3 = triple;
                             PINSIM_ARITY_VARIABLE = whole bodies / rings of any length) */
  const char* name;     /**< e.g. "damped_spring" */
  const char* version;  /**< e.g. "1.0.0" */
  const char* doc;      /**< one paragraph */
  const pinsim_param* params;
  uint32_t n_params;
  uint32_t capabilities;                                              /**< PINSIM_CAP_* */
  void* (*create)(const pinsim_create_args* args, pinsim_error* err); /**< NULL on error */
  void (*destroy)(void* self);
  pinsim_force_api force;     /**< used when kind == PINSIM_KIND_FORCE */
  pinsim_backend_api backend; /**< used when kind == PINSIM_KIND_BACKEND */
  /* A 4.0 table ends here (PINSIM_ABI_MIN_TABLE_SIZE). Each entry below names the minor that
   * added it and is absent from a table that ends before it (PINSIM_TABLE_HAS) or whose
   * minor is older. A new minor appends its entries after the last one. */
  uint32_t abi_minor; /**< 4.1: PINSIM_ABI_MINOR the plugin was built with (absent: 0) */
  /** 4.2, forces: fills *out with the instance's constraints (pinsim_constraint_set). NULL
   *  unless PINSIM_CAP_CONSTRAINTS. */
  int (*constraint_set)(void* self, pinsim_constraint_set* out, pinsim_error* err);
  /** 4.2, forces: for the `count` constraints listed in `which` (indices below the set's
   *  count), at positions x (2n), c[k] = C of constraint which[k] and its gradient dC/dp
   *  into dc: the listed constraints one after another, each as 2 L doubles (d/dx, d/dy of its
   *  particles in its order; L its particle count). Only reads the instance: the host may call
   *  it from several threads at once, each call with its own arrays and error buffer. NULL
   *  unless PINSIM_CAP_CONSTRAINTS. */
  int (*constraints)(void* self, const double* x, const uint64_t* which, uint64_t count, double* c,
                     double* dc, pinsim_error* err);
  /** 4.3, backends: from now on every advance() reports its drift to `sink`
   *  (pinsim_drift_sink; NULL: stop). It may march particles one by one and skip caches
   *  while recording, but the state it reaches is the same to the bit. NULL for a backend
   *  with nothing to record (no contacts) or that cannot differentiate its step. */
  int (*record_drift)(void* self, const pinsim_drift_sink* sink, pinsim_error* err);
  /** 4.4, forces: df += d f / d theta at s (2n doubles), theta being component `component`
   *  (0 for a REAL; 0 or 1 for a VEC2) of parameter number `param` (an index into params),
   *  which is flagged PINSIM_PARAM_DIFFERENTIABLE. The derivative at the instance's own
   *  parameter values, with everything it took from the initial state at create() (rest
   *  lengths, angles, areas) held fixed: the limit of (f_plus - f_minus) / (2 eps) for two
   *  instances created with theta moved by +-eps. The host calls it only for flagged
   *  parameters (`pinsim grad`, whose output then says "plugin" for them, and check-plugin,
   *  which compares it with central differences of add_force over the parameter). Only reads
   *  the instance. NULL unless PINSIM_CAP_DPARAM. */
  int (*add_dforce_dparam)(void* self, const pinsim_state_view* s, uint32_t param,
                           uint32_t component, double* df, pinsim_error* err);
  /** 4.4, forces: the Jacobians' transposed products with w (2n doubles) at s:
   *  gx += (df/dx)^T w, and gv += (df/dv)^T w unless gv is NULL; the same numbers, to rounding,
   *  as add_jacobians' entries multiplied out, without handing them over (what the host's
   *  adjoint of a run takes each step, docs/gradients.md). Only reads the instance. NULL
   *  unless PINSIM_CAP_JACOBIAN_PRODUCTS. */
  int (*add_jacobian_products)(void* self, const pinsim_state_view* s, const double* w, double* gx,
                               double* gv, pinsim_error* err);
  /** 4.5, forces: add_jacobian_products' gx and gv and, in the same pass over the elements,
   *  gp[j] += w . d f / d theta_j at s for every component theta_j of the parameters flagged
   *  PINSIM_PARAM_DIFFERENTIABLE, numbered in the table's order (a REAL one slot, a VEC2 two):
   *  the whole of a force's work in one step of the host's adjoint, its geometry computed once.
   *  The same numbers, to rounding, as add_jacobian_products and the dot products of w with
   *  add_dforce_dparam's. gv may be NULL; gp is not. Only reads the instance. NULL unless
   *  PINSIM_CAP_ADJOINT_PRODUCTS. */
  int (*add_adjoint_products)(void* self, const pinsim_state_view* s, const double* w, double* gx,
                              double* gv, double* gp, pinsim_error* err);
} pinsim_plugin;

/** Length of the smallest table of this major: a 4.0 table, every entry up to `backend`. */
#define PINSIM_ABI_MIN_TABLE_SIZE offsetof(pinsim_plugin, abi_minor)

/** Whether the table at `t` (a const pinsim_plugin*) reaches past `member`: read an entry a
 *  minor version added only when this holds (and the table's minor is at least that one). */
#define PINSIM_TABLE_HAS(t, member) \
  ((size_t)(t)->struct_size >= offsetof(pinsim_plugin, member) + sizeof((t)->member))

typedef const pinsim_plugin* (*pinsim_entry_fn)(void);

#ifdef __cplusplus
}
#endif

#endif /* PINSIM_ABI_H */
