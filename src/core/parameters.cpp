#include "flexipde/parameters.hpp"
#include "flexipde/io.hpp"
#include <cmath>
#include <cstring>
#include <fstream>

namespace flexipde {

PetscInt Parameters::add(const std::string &name, ParamKind kind, PetscReal lower, PetscReal initial) {
  ParamInfo pi;
  pi.name = name, pi.kind = kind, pi.lower = lower, pi.initial = initial;
  info_.push_back(pi);
  return static_cast<PetscInt>(info_.size()) - 1;
}

PetscInt Parameters::add_vector(const std::string &name, const std::vector<PetscReal> &initial, PetscReal lower) {
  ParamInfo pi;
  pi.name = name, pi.kind = ParamKind::Vector, pi.lower = lower, pi.initial = 0.0;
  pi.entries = (PetscInt)initial.size(), pi.initial_entries = initial;
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
  for (auto &pi : info_) { // then the vectors, also on rank 0
    if (pi.kind != ParamKind::Vector) continue;
    pi.local_offset = off;
    pi.local_size = rank == 0 ? pi.entries : 0;
    pi.global_start = nscalar;
    nscalar += pi.entries;
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

PetscErrorCode Parameters::vector_values(Vec p, PetscInt k, std::vector<PetscReal> &values) const {
  const ParamInfo &pi = info_[k];
  PetscFunctionBeginUser;
  PetscCheck(pi.kind == ParamKind::Vector, PETSC_COMM_SELF, PETSC_ERR_ARG_WRONG, "%s is not a vector", pi.name.c_str());
  values.assign(pi.entries, 0.0);
  {
    ConstArray a(p);
    PetscCall(a.error());
    for (PetscInt i = 0; i < pi.local_size; ++i) values[i] = PetscRealPart(a[pi.local_offset + i]);
  }
  PetscCallMPI(MPI_Bcast(values.data(), (int)pi.entries, MPIU_REAL, 0, grid_->comm()));
  PetscFunctionReturn(0);
}

PetscErrorCode Parameters::set_vector(Vec p, PetscInt k, const std::vector<PetscReal> &values) const {
  const ParamInfo &pi = info_[k];
  PetscFunctionBeginUser;
  PetscCheck(pi.kind == ParamKind::Vector, PETSC_COMM_SELF, PETSC_ERR_ARG_WRONG, "%s is not a vector", pi.name.c_str());
  PetscCheck((PetscInt)values.size() == pi.entries, PETSC_COMM_SELF, PETSC_ERR_ARG_SIZ,
             "%s has %" PetscInt_FMT " entries, got %zu values", pi.name.c_str(), pi.entries, values.size());
  Array a(p);
  PetscCall(a.error());
  for (PetscInt i = 0; i < pi.local_size; ++i) a[pi.local_offset + i] = values[i];
  PetscFunctionReturn(0);
}

PetscErrorCode Parameters::add_local_sums(Vec grad, PetscInt k, const PetscReal *local) const {
  const ParamInfo &pi = info_[k];
  std::vector<PetscReal> total(pi.entries, 0.0);
  PetscFunctionBeginUser;
  PetscCheck(pi.kind == ParamKind::Vector, PETSC_COMM_SELF, PETSC_ERR_ARG_WRONG, "%s is not a vector", pi.name.c_str());
  PetscCallMPI(MPI_Reduce(local, total.data(), (int)pi.entries, MPIU_REAL, MPI_SUM, 0, grid_->comm()));
  Array G(grad); // on every rank (see add_local_sum)
  PetscCall(G.error());
  for (PetscInt i = 0; i < pi.local_size; ++i) G[pi.local_offset + i] += total[i];
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
  PetscCheck(info_[k].kind != ParamKind::Vector, PETSC_COMM_SELF, PETSC_ERR_ARG_WRONG, "%s is a vector, not a field",
             info_[k].name.c_str());
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

// Numbers from a text file (whitespace or commas between them), or the series /vectors/<name> of an
// HDF5 file (recognised by its signature).
static PetscErrorCode read_vector_file(MPI_Comm comm, const char *file, const char *name, const char *dataset,
                                       std::vector<PetscReal> &v) {
  char sig[8] = {0};
  PetscFunctionBeginUser;
  std::ifstream in(file, std::ios::binary);
  PetscCheck(in.good(), comm, PETSC_ERR_FILE_OPEN, "-%s_file %s cannot be read", name, file);
  in.read(sig, 8);
  if (in.gcount() == 8 && !std::memcmp(sig, "\x89HDF\r\n\x1a\n", 8)) {
    H5Reader r;
    bool exists = false;
    PetscCall(r.open(comm, file));
    PetscCall(r.has("/vectors", dataset, &exists));
    PetscCheck(exists, comm, PETSC_ERR_FILE_UNEXPECTED, "-%s_file %s has no dataset /vectors/%s", name, file, dataset);
    PetscCall(r.read_series("/vectors", dataset, v));
    PetscCall(r.close());
    PetscFunctionReturn(0);
  }
  in.clear();
  in.seekg(0);
  std::string tok;
  v.clear();
  while (in >> tok) {
    for (char &c : tok)
      if (c == ',') c = ' ';
    char *end = nullptr;
    const char *s = tok.c_str();
    while (*s) {
      while (*s == ' ') ++s;
      if (!*s) break;
      const double x = std::strtod(s, &end);
      PetscCheck(end != s, comm, PETSC_ERR_FILE_UNEXPECTED, "-%s_file %s: \"%s\" is not a number", name, file, s);
      v.push_back(x);
      s = end;
    }
  }
  PetscFunctionReturn(0);
}

// A vector parameter: -<prefix> v1,v2,... or -<prefix>_file F, else its declared defaults.
static PetscErrorCode vector_from_options(const Parameters &params, PetscInt k, const char *prefix, Vec p) {
  const ParamInfo &pi = params.info(k);
  MPI_Comm comm = params.grid()->comm();
  const std::string pre = std::string("-") + prefix;
  std::vector<PetscReal> v = pi.initial_entries;
  if (v.empty()) v.assign(pi.entries, pi.initial);
  std::vector<PetscReal> given(pi.entries + 1);
  PetscInt n = pi.entries + 1;
  PetscBool set = PETSC_FALSE, fset = PETSC_FALSE;
  char file[PETSC_MAX_PATH_LEN] = "";
  PetscFunctionBeginUser;
  const std::string title = "Parameter vector " + std::string(prefix) + " (" + std::to_string(pi.entries) + " entries)";
  PetscOptionsBegin(comm, nullptr, title.c_str(), "Parameters");
  PetscCall(PetscOptionsRealArray(pre.c_str(), "All entries, comma-separated", "Parameters", given.data(), &n, &set));
  PetscCall(PetscOptionsString((pre + "_file").c_str(), "File of the entries: text, or HDF5 with /vectors/<name>",
                               "Parameters", file, file, sizeof(file), &fset));
  PetscOptionsEnd();
  PetscCheck(!(set && fset), comm, PETSC_ERR_ARG_INCOMP, "Give %s or %s_file, not both", pre.c_str(), pre.c_str());
  if (set) {
    PetscCheck(n == pi.entries, comm, PETSC_ERR_ARG_SIZ, "%s needs %" PetscInt_FMT " values, got %" PetscInt_FMT, pre.c_str(),
               pi.entries, n);
    v.assign(given.begin(), given.begin() + n);
  }
  if (fset) {
    PetscCall(read_vector_file(comm, file, prefix, pi.name.c_str(), v));
    PetscCheck((PetscInt)v.size() == pi.entries, comm, PETSC_ERR_ARG_SIZ,
               "%s_file %s holds %zu values, %s has %" PetscInt_FMT, pre.c_str(), file, v.size(), prefix, pi.entries);
  }
  for (PetscReal x : v) PetscCheck(std::isfinite(x), comm, PETSC_ERR_ARG_WRONG, "%s: non-finite value", pre.c_str());
  PetscCall(params.set_vector(p, k, v));
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
  if (pi.kind == ParamKind::Vector) {
    PetscCall(vector_from_options(params, k, prefix, p));
    PetscFunctionReturn(0);
  }
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
