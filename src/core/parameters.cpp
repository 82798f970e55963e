#include "flexipde/parameters.hpp"
#include <cmath>

namespace flexipde {

PetscInt Parameters::add(const std::string &name, ParamKind kind, PetscReal lower, PetscReal initial) {
  ParamInfo pi;
  pi.name = name, pi.kind = kind, pi.lower = lower, pi.initial = initial;
  info_.push_back(pi);
  return static_cast<PetscInt>(info_.size()) - 1;
}

PetscInt Parameters::find(const std::string &name) const {
  for (PetscInt k = 0; k < count(); ++k)
    if (info_[k].name == name) return k;
  return -1;
}

PetscErrorCode Parameters::finalize(const Grid &grid) {
  PetscMPIInt rank;
  PetscFunctionBeginUser;
  PetscCallMPI(MPI_Comm_rank(grid.comm(), &rank));
  grid_ = &grid;
  PetscInt off = 0, nscalar = 0;
  for (auto &pi : info_) { // scalars first, owned by rank 0, whose range starts at 0
    if (pi.kind != ParamKind::Scalar) continue;
    pi.local_offset = off;
    pi.local_size = rank == 0 ? 1 : 0;
    pi.global_start = nscalar++;
    off += pi.local_size;
  }
  for (auto &pi : info_) {
    if (pi.kind != ParamKind::Field) continue;
    pi.local_offset = off;
    pi.local_size = grid.local_points();
    off += pi.local_size;
  }
  nlocal_ = off;
  PetscCallMPI(MPI_Allreduce(&nlocal_, &nglobal_, 1, MPIU_INT, MPI_SUM, grid.comm()));
  PetscCallMPI(MPI_Scan(&nlocal_, &rstart_, 1, MPIU_INT, MPI_SUM, grid.comm()));
  rstart_ -= nlocal_;
  for (auto &pi : info_)
    if (pi.kind == ParamKind::Field) pi.global_start = rstart_ + pi.local_offset;
  finalized_ = true;
  PetscFunctionReturn(0);
}

PetscErrorCode Parameters::create_vec(Vec *p) const {
  PetscFunctionBeginUser;
  PetscCheck(finalized_, PETSC_COMM_SELF, PETSC_ERR_ORDER, "Parameters::finalize() must come first");
  PetscCall(VecCreateMPI(grid_->comm(), nlocal_, nglobal_, p));
  PetscCall(VecSet(*p, 0.0));
  PetscFunctionReturn(0);
}

PetscErrorCode Parameters::scalar(Vec p, PetscInt k, PetscReal *value) const {
  PetscReal v = 0;
  PetscMPIInt rank;
  PetscFunctionBeginUser;
  PetscCheck(info_[k].kind == ParamKind::Scalar, PETSC_COMM_SELF, PETSC_ERR_ARG_WRONG, "%s is not a scalar",
             info_[k].name.c_str());
  PetscCallMPI(MPI_Comm_rank(grid_->comm(), &rank));
  {
    ConstArray a(p);
    PetscCall(a.error());
    if (rank == 0) v = PetscRealPart(a[info_[k].local_offset]);
  }
  PetscCallMPI(MPI_Bcast(&v, 1, MPIU_REAL, 0, grid_->comm()));
  *value = v;
  PetscFunctionReturn(0);
}

PetscErrorCode Parameters::set_scalar(Vec p, PetscInt k, PetscReal value) const {
  PetscFunctionBeginUser;
  PetscCheck(info_[k].kind == ParamKind::Scalar, PETSC_COMM_SELF, PETSC_ERR_ARG_WRONG, "%s is not a scalar",
             info_[k].name.c_str());
  Array a(p);
  PetscCall(a.error());
  if (info_[k].local_size) a[info_[k].local_offset] = value;
  PetscFunctionReturn(0);
}

PetscErrorCode Parameters::add_local_sum(Vec grad, PetscInt k, PetscReal local) const {
  PetscReal total = 0;
  PetscFunctionBeginUser;
  PetscCheck(info_[k].kind == ParamKind::Scalar, PETSC_COMM_SELF, PETSC_ERR_ARG_WRONG, "%s is not a scalar",
             info_[k].name.c_str());
  if (grad == deferred_) {
    pending_[k] += local;
    PetscFunctionReturn(0);
  }
  PetscCallMPI(MPI_Reduce(&local, &total, 1, MPIU_REAL, MPI_SUM, 0, grid_->comm()));
  // The array is taken on every rank, not only where the scalar lives: getting it marks grad as
  // changed, and a rank that skipped it would reuse a cached norm and skip the collective of the
  // next VecNorm that the others enter.
  Array G(grad);
  PetscCall(G.error());
  if (info_[k].local_size) G[info_[k].local_offset] += total;
  PetscFunctionReturn(0);
}

void Parameters::defer_sums(Vec grad) const {
  deferred_ = grad;
  pending_.assign(info_.size(), 0.0);
}

PetscErrorCode Parameters::flush_sums() const {
  PetscFunctionBeginUser;
  if (!deferred_) PetscFunctionReturn(0);
  Vec grad = deferred_;
  deferred_ = nullptr;
  std::vector<PetscReal> total(pending_.size(), 0.0);
  if (!pending_.empty())
    PetscCallMPI(MPI_Reduce(pending_.data(), total.data(), (int)pending_.size(), MPIU_REAL, MPI_SUM, 0, grid_->comm()));
  Array G(grad); // on every rank (see add_local_sum)
  PetscCall(G.error());
  for (size_t k = 0; k < info_.size(); ++k)
    if (info_[k].kind == ParamKind::Scalar && info_[k].local_size) G[info_[k].local_offset] += total[k];
  PetscFunctionReturn(0);
}

PetscErrorCode Parameters::add_pointwise(Vec grad, PetscInt k, const std::vector<PetscReal> &g) const {
  const ParamInfo &pi = info_[k];
  PetscFunctionBeginUser;
  if (pi.kind == ParamKind::Scalar) {
    PetscReal sum = 0;
    for (PetscReal x : g) sum += x;
    PetscCall(add_local_sum(grad, k, sum));
    PetscFunctionReturn(0);
  }
  Array G(grad);
  PetscCall(G.error());
  for (PetscInt il = 0; il < pi.local_size; ++il) G[pi.local_offset + il] += g[il];
  PetscFunctionReturn(0);
}

PetscErrorCode Parameters::set_field(Vec p, PetscInt k, Vec field) const {
  PetscFunctionBeginUser;
  PetscCheck(info_[k].kind == ParamKind::Field, PETSC_COMM_SELF, PETSC_ERR_ARG_WRONG, "%s is not a field",
             info_[k].name.c_str());
  Array a(p);
  ConstArray f(field);
  PetscCall(a.error());
  PetscCall(f.error());
  for (PetscInt i = 0; i < info_[k].local_size; ++i) a[info_[k].local_offset + i] = f[i];
  PetscFunctionReturn(0);
}

PetscErrorCode Parameters::as_field(Vec p, PetscInt k, Vec field) const {
  PetscFunctionBeginUser;
  if (info_[k].kind == ParamKind::Field) {
    PetscCall(get_field(p, k, field));
  } else {
    PetscReal v;
    PetscCall(scalar(p, k, &v));
    PetscCall(VecSet(field, v));
  }
  PetscFunctionReturn(0);
}

PetscErrorCode Parameters::get_field(Vec p, PetscInt k, Vec field) const {
  PetscFunctionBeginUser;
  PetscCheck(info_[k].kind == ParamKind::Field, PETSC_COMM_SELF, PETSC_ERR_ARG_WRONG, "%s is not a field",
             info_[k].name.c_str());
  ConstArray a(p);
  Array f(field);
  PetscCall(a.error());
  PetscCall(f.error());
  for (PetscInt i = 0; i < info_[k].local_size; ++i) f[i] = a[info_[k].local_offset + i];
  PetscFunctionReturn(0);
}

PetscErrorCode fill_from_options(const Parameters &params, PetscInt k, const char *prefix, PetscReal default_value,
                                 Vec p) {
  const ParamInfo &pi = params.info(k);
  const Grid &g = *params.grid();
  std::string pre = std::string("-") + prefix;
  PetscReal value = default_value, left = default_value, right = default_value, bump = 0.0, center = 0.5 * (g.x0() + g.x1()),
            width = 0.1 * (g.x1() - g.x0());
  const char *types[] = {"constant", "linear", "gaussian"};
  PetscInt type = 0;
  PetscFunctionBeginUser;
  // One help section per parameter: PETSc lists a section title only once.
  const std::string title = "Parameter " + std::string(prefix);
  PetscOptionsBegin(g.comm(), nullptr, title.c_str(), "Parameters");
  PetscCall(PetscOptionsReal(pre.c_str(), "Constant value of the parameter", "Parameters", value, &value, nullptr));
  if (pi.kind == ParamKind::Field) {
    left = right = value;
    PetscCall(PetscOptionsEList((pre + "_profile").c_str(), "Shape of the field", "Parameters", types, 3, types[type],
                                &type, nullptr));
    PetscCall(PetscOptionsReal((pre + "_left").c_str(), "Linear profile: value at the left end", "Parameters", left,
                               &left, nullptr));
    PetscCall(PetscOptionsReal((pre + "_right").c_str(), "Linear profile: value at the right end", "Parameters", right,
                               &right, nullptr));
    PetscCall(PetscOptionsReal((pre + "_bump").c_str(), "Gaussian profile: height of the bump added to the value",
                               "Parameters", bump, &bump, nullptr));
    PetscCall(PetscOptionsReal((pre + "_center").c_str(), "Gaussian profile: centre", "Parameters", center, &center,
                               nullptr));
    PetscCall(PetscOptionsReal((pre + "_width").c_str(), "Gaussian profile: width", "Parameters", width, &width,
                               nullptr));
  }
  PetscOptionsEnd();
  Array a(p);
  PetscCall(a.error());
  if (pi.kind == ParamKind::Scalar) {
    if (pi.local_size) a[pi.local_offset] = value;
  } else {
    for (PetscInt i = 0; i < pi.local_size; ++i) {
      const PetscReal x = g.x(g.xs() + i % g.xm()), s = (x - g.x0()) / (g.x1() - g.x0());
      PetscReal v = value;
      if (type == 1) v = left + (right - left) * s;
      if (type == 2) v = value + bump * std::exp(-std::pow((x - center) / width, 2));
      a[pi.local_offset + i] = v;
    }
  }
  PetscFunctionReturn(0);
}

} // namespace flexipde
