#include "gradients/drift_record.hpp"

namespace pinsim::grad {
namespace {

Vec2 v2(const double* p) { return {p[0], p[1]}; }
Mat2 m2(const double* p) {
  Mat2 m;
  m << p[0], p[2], p[1], p[3];  // column-major in the ABI
  return m;
}

}  // namespace

DriftRecording::DriftRecording(BackendInstance& backend) : backend_(backend) {
  sink_ = {this, &on_begin, &on_pair, &on_impact, &on_finding};
  backend_.record_drift(&sink_);
}

DriftRecording::~DriftRecording() {
  try {
    backend_.record_drift(nullptr);
  } catch (...) {  // stopping cannot be reported from a destructor; the run is over anyway
  }
}

void DriftRecording::on_begin(void* self, const pinsim_state_view* s, double dt) {
  auto* r = static_cast<DriftRecording*>(self);
  if (r->tape_ == nullptr) return;
  DriftTape& d = *r->tape_;
  const auto n = static_cast<Eigen::Index>(s->n);
  d.t0 = s->t;
  d.h = dt;
  d.x_in = Eigen::Map<const Eigen::Matrix2Xd>(s->x, 2, n);
  d.v_in = Eigen::Map<const Eigen::Matrix2Xd>(s->v, 2, n);
  d.inv_mass = Eigen::Map<const Eigen::VectorXd>(s->inv_mass, n);
  d.impacts.clear();
  d.pairs.clear();
  d.findings.clear();
  r->began_ = true;
}

void DriftRecording::on_pair(void* self, const pinsim_drift_pair* h) {
  auto* r = static_cast<DriftRecording*>(self);
  if (r->tape_ == nullptr || !r->began_) return;
  PairHit p;
  p.i = static_cast<uint32_t>(h->i);
  p.j = static_cast<uint32_t>(h->j);
  p.tau = h->tau;
  p.xr_i = v2(h->xr_i);
  p.vc_i = v2(h->vc_i);
  p.tr_i = h->tr_i;
  p.xr_j = v2(h->xr_j);
  p.vc_j = v2(h->vc_j);
  p.tr_j = h->tr_j;
  p.radius_sum = h->radius_sum;
  p.w_i = h->w_i;
  p.w_j = h->w_j;
  p.restitution = h->restitution;
  p.touching = h->touching != 0;
  r->tape_->pairs.push_back(p);
}

void DriftRecording::on_impact(void* self, const pinsim_drift_impact* m) {
  auto* r = static_cast<DriftRecording*>(self);
  if (r->tape_ == nullptr || !r->began_) return;
  Impact im;
  im.kind = m->kind == PINSIM_IMPACT_CHANGE    ? ImpactKind::kChange
            : m->kind == PINSIM_IMPACT_IN_BAND ? ImpactKind::kInBand
                                               : ImpactKind::kToi;
  im.particle = static_cast<uint32_t>(m->particle);
  im.tau = m->tau;
  im.p = v2(m->p);
  im.v_before = v2(m->v_before);
  im.v_after = v2(m->v_after);
  im.obstacle = m->obstacle;
  im.n = v2(m->n);
  im.n_p = m2(m->n_p);
  im.n_t = v2(m->n_t);
  im.phi = m->phi;
  im.phi_t = m->phi_t;
  im.offset = m->offset;
  im.u = v2(m->u);
  im.u_p = m2(m->u_p);
  im.u_t = v2(m->u_t);
  im.restitution = m->restitution;
  im.friction = m->friction;
  im.kick = m->kick;
  im.resting = (m->flags & PINSIM_IMPACT_RESTING) != 0;
  im.emitted = (m->flags & PINSIM_IMPACT_EMITTED) != 0;
  im.pair = m->pair;
  im.side = static_cast<uint8_t>(m->side);
  r->tape_->impacts.push_back(im);
}

void DriftRecording::on_finding(void* self, const pinsim_drift_finding* f) {
  auto* r = static_cast<DriftRecording*>(self);
  if (r->tape_ == nullptr || !r->began_) return;
  Finding x;
  x.kind = static_cast<Finding::Kind>(f->kind);
  x.particle = static_cast<uint32_t>(f->particle);
  x.obstacle = f->obstacle;
  x.t = f->t;
  x.margin = f->margin;
  r->tape_->findings.push_back(x);
}

}  // namespace pinsim::grad
