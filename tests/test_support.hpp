// Helpers shared by the unit tests (header only; tests/CMakeLists.txt compiles test_*.cpp).
//
// Collective safety: every helper here is either purely local and deterministic (so every rank
// computes the same thing) or collective over the communicator it is given. Values that tests
// assert on are reduced over the communicator first, so every rank takes the same branch and an
// ASSERT that returns early does so on every rank at once.
#pragma once
#include "flexipde/petsc.hpp"
#include "flexipde/scene.hpp"
#include <algorithm>
#include <cmath>
#include <functional>
#include <gtest/gtest.h>
#include <string>
#include <utility>
#include <vector>

// Assert that a PETSc-style call succeeded (collective calls fail on every rank alike).
#define PETSC_ASSERT_OK(expr) ASSERT_EQ((PetscErrorCode)0, (expr)) << #expr
#define PETSC_EXPECT_OK(expr) EXPECT_EQ((PetscErrorCode)0, (expr)) << #expr

namespace flexipde_test {

// Sets options in the global PETSc options database for its lifetime and restores the previous
// state afterwards (clears options that were unset, restores values that an enclosing scope set),
// so that tests do not leak options into each other and scopes can be nested.
class ScopedOptions {
public:
  ScopedOptions() = default;
  ScopedOptions(std::initializer_list<std::pair<const char *, const char *>> opts) {
    for (auto &o : opts) set(o.first, o.second);
  }
  ScopedOptions(const ScopedOptions &) = delete;
  ScopedOptions &operator=(const ScopedOptions &) = delete;
  ~ScopedOptions() {
    for (auto it = saved_.rbegin(); it != saved_.rend(); ++it) {
      if (!it->was_set) (void)PetscOptionsClearValue(nullptr, it->name.c_str());
      else (void)PetscOptionsSetValue(nullptr, it->name.c_str(), it->value.empty() ? nullptr : it->value.c_str());
    }
  }
  void set(const std::string &name, const std::string &value) {
    Saved s{name, PETSC_FALSE, ""};
    char buf[PETSC_MAX_PATH_LEN] = "";
    (void)PetscOptionsGetString(nullptr, nullptr, name.c_str(), buf, sizeof(buf), &s.was_set);
    s.value = buf;
    saved_.push_back(s);
    (void)PetscOptionsSetValue(nullptr, name.c_str(), value.c_str());
  }

private:
  struct Saved {
    std::string name;
    PetscBool was_set;
    std::string value;
  };
  std::vector<Saved> saved_;
};

// While alive, PETSc errors return their code silently instead of printing a traceback.
class QuietErrors {
public:
  QuietErrors() { (void)PetscPushErrorHandler(PetscReturnErrorHandler, nullptr); }
  ~QuietErrors() { (void)PetscPopErrorHandler(); }
  QuietErrors(const QuietErrors &) = delete;
  QuietErrors &operator=(const QuietErrors &) = delete;
};

// Every rank's copy of a distributed Vec, in global order (collective).
inline PetscErrorCode gather_all(Vec v, std::vector<PetscReal> &out) {
  VecScatter sc;
  Vec all;
  PetscInt n;
  PetscFunctionBeginUser;
  PetscCall(VecScatterCreateToAll(v, &sc, &all));
  PetscCall(VecScatterBegin(sc, v, all, INSERT_VALUES, SCATTER_FORWARD));
  PetscCall(VecScatterEnd(sc, v, all, INSERT_VALUES, SCATTER_FORWARD));
  PetscCall(VecGetSize(all, &n));
  const PetscScalar *a;
  PetscCall(VecGetArrayRead(all, &a));
  out.resize(n);
  for (PetscInt i = 0; i < n; ++i) out[i] = PetscRealPart(a[i]);
  PetscCall(VecRestoreArrayRead(all, &a));
  PetscCall(VecDestroy(&all));
  PetscCall(VecScatterDestroy(&sc));
  PetscFunctionReturn(0);
}

// Uniform random entries in [lo, hi] from a fixed seed (collective on the Vec's communicator).
// v = uniform values in [lo, hi) from `seed`, entry i of the global vector being the i-th draw on any
// number of ranks (VecSetRandom draws each rank's entries from the same sequence, so its vector depends
// on the partition; here every rank draws the whole sequence and keeps its slice): a test sees the same
// direction on 1, 2 or 3 ranks, and on 1 rank the same values as VecSetRandom.
inline PetscErrorCode fill_random(Vec v, PetscReal lo, PetscReal hi, unsigned long seed) {
  PetscRandom rnd;
  PetscInt begin, end;
  PetscScalar *a;
  PetscFunctionBeginUser;
  PetscCall(PetscRandomCreate(PETSC_COMM_SELF, &rnd));
  PetscCall(PetscRandomSetInterval(rnd, lo, hi));
  PetscCall(PetscRandomSetSeed(rnd, seed));
  PetscCall(PetscRandomSeed(rnd));
  PetscCall(VecGetOwnershipRange(v, &begin, &end));
  PetscCall(VecGetArrayWrite(v, &a));
  for (PetscInt i = 0; i < end; ++i) {
    PetscScalar r;
    PetscCall(PetscRandomGetValue(rnd, &r));
    if (i >= begin) a[i - begin] = r;
  }
  PetscCall(VecRestoreArrayWrite(v, &a));
  PetscCall(PetscRandomDestroy(&rnd));
  PetscFunctionReturn(0);
}

inline PetscReal dot(Vec a, Vec b) {
  PetscScalar d = 0;
  if (VecDot(a, b, &d)) return NAN;
  return PetscRealPart(d);
}

inline PetscReal norm(Vec a, NormType t = NORM_2) {
  PetscReal n = 0;
  if (VecNorm(a, t, &n)) return NAN;
  return n;
}

// |a - b| / max(|a|, |b|, tiny): relative difference of two numbers.
inline PetscReal rel_diff(PetscReal a, PetscReal b) {
  const PetscReal s = std::max(std::max(std::fabs(a), std::fabs(b)), (PetscReal)1e-300);
  return std::fabs(a - b) / s;
}

// ||a - b||_inf / ||b||_inf (collective).
inline PetscReal rel_diff(Vec a, Vec b) {
  Vec d;
  if (VecDuplicate(a, &d)) return NAN;
  if (VecWAXPY(d, -1.0, b, a)) return NAN;
  const PetscReal r = norm(d, NORM_INFINITY) / std::max(norm(b, NORM_INFINITY), (PetscReal)1e-300);
  (void)VecDestroy(&d);
  return r;
}

inline bool is_rank0(MPI_Comm comm = PETSC_COMM_WORLD) {
  int r = 0;
  MPI_Comm_rank(comm, &r);
  return r == 0;
}

// A scene from the options with p from -<param> options, p_true from -true_<param> options, and
// synthetic data made from p_true: the set-up of every gradient and inversion test.
struct SceneProblem {
  flexipde::Scene scene;
  flexipde::OwnedVec p, p_true;
  PetscErrorCode setup(MPI_Comm comm) {
    PetscFunctionBeginUser;
    PetscCall(scene.setup(comm));
    PetscCall(scene.params.create_vec(p.out()));
    PetscCall(scene.params.create_vec(p_true.out()));
    PetscCall(scene.parameters_from_options("", p));
    PetscCall(scene.parameters_from_options("true_", p_true));
    PetscCall(scene.make_synthetic_data(p_true));
    PetscFunctionReturn(0);
  }
};

// max_i |a_i - b_i| / max_i |b_i| (entrywise comparison of gathered vectors).
inline PetscReal max_rel_diff(const std::vector<PetscReal> &a, const std::vector<PetscReal> &b) {
  PetscReal diff = 0, scale = 0;
  for (size_t i = 0; i < a.size() && i < b.size(); ++i) {
    diff = std::max(diff, std::fabs(a[i] - b[i]));
    scale = std::max(scale, std::fabs(b[i]));
  }
  return scale > 0 ? diff / scale : (diff > 0 ? INFINITY : 0);
}

// Expects a parallel run (value Jpar, gathered gradient a) to match a serial one (Jser, b) to 1e-10
// relative; the worst difference over ranks decides, so every rank takes the same branch.
inline void expect_matches_serial(const std::string &label, PetscReal Jpar, PetscReal Jser,
                                  const std::vector<PetscReal> &a, const std::vector<PetscReal> &b) {
  EXPECT_EQ(a.size(), b.size());
  PetscReal scale = 0;
  for (PetscReal x : b) scale = std::max(scale, std::fabs(x));
  PetscReal worst[2] = {rel_diff(Jpar, Jser), max_rel_diff(a, b)};
  MPI_Allreduce(MPI_IN_PLACE, worst, 2, MPIU_REAL, MPI_MAX, PETSC_COMM_WORLD);
  PetscMPIInt size;
  MPI_Comm_size(PETSC_COMM_WORLD, &size);
  PetscPrintf(PETSC_COMM_WORLD, "  [%s, %d ranks vs serial] J = %.12e, rel diff J %.2e, gradient %.2e\n", label.c_str(),
              (int)size, (double)Jpar, (double)worst[0], (double)worst[1]);
  EXPECT_GT(Jser, 0.0);
  EXPECT_GT(scale, 0.0);
  EXPECT_LE(worst[0], 1e-10);
  EXPECT_LE(worst[1], 1e-10);
}

// The parameter-shaped vector v of a scene on every rank: scalars by value, fields in the grid's natural
// order (a 2D DMDA's global order is per-rank blocks), so that scenes on any number of ranks compare
// entry by entry (collective).
inline PetscErrorCode natural_parameters(const flexipde::Scene &s, Vec v, std::vector<PetscReal> &out) {
  std::vector<PetscReal> part;
  PetscFunctionBeginUser;
  out.clear();
  for (PetscInt k = 0; k < s.params.count(); ++k) {
    if (s.params.info(k).kind == flexipde::ParamKind::Scalar) {
      PetscReal value;
      PetscCall(s.params.scalar(v, k, &value));
      out.push_back(value);
      continue;
    }
    flexipde::OwnedVec f, nat;
    PetscCall(DMCreateGlobalVector(s.grid.dm(), f.out()));
    PetscCall(DMDACreateNaturalVector(s.grid.dm(), nat.out()));
    PetscCall(s.params.get_field(v, k, f));
    PetscCall(DMDAGlobalToNaturalBegin(s.grid.dm(), f, INSERT_VALUES, nat));
    PetscCall(DMDAGlobalToNaturalEnd(s.grid.dm(), f, INSERT_VALUES, nat));
    PetscCall(gather_all(nat, part));
    out.insert(out.end(), part.begin(), part.end());
  }
  PetscFunctionReturn(0);
}

// The scene of the current options set up on PETSC_COMM_WORLD and on PETSC_COMM_SELF (each rank the
// serial problem): J and dJ/dp (Scene::gradient, summed over a survey's shots) the same (1e-10).
// `prepare`, if given, is applied to both scenes after their set-up.
inline void expect_parallel_matches_serial(const std::string &label,
                                           const std::function<PetscErrorCode(flexipde::Scene &)> &prepare = nullptr) {
  SceneProblem par, ser;
  PETSC_ASSERT_OK(par.setup(PETSC_COMM_WORLD));
  PETSC_ASSERT_OK(ser.setup(PETSC_COMM_SELF));
  if (prepare) {
    PETSC_ASSERT_OK(prepare(par.scene));
    PETSC_ASSERT_OK(prepare(ser.scene));
  }
  flexipde::OwnedVec gpar, gser;
  PETSC_ASSERT_OK(VecDuplicate(par.p, gpar.out()));
  PETSC_ASSERT_OK(VecDuplicate(ser.p, gser.out()));
  PetscReal Jpar, Jser;
  PETSC_ASSERT_OK(par.scene.gradient(par.p, &Jpar, gpar));
  PETSC_ASSERT_OK(ser.scene.gradient(ser.p, &Jser, gser));
  std::vector<PetscReal> a, b;
  PETSC_ASSERT_OK(natural_parameters(par.scene, gpar, a));
  PETSC_ASSERT_OK(natural_parameters(ser.scene, gser, b));
  expect_matches_serial(label, Jpar, Jser, a, b);
}

// With a diffusivity field D among the scene's parameters: p's D becomes random in [lo, hi], so every
// entry of it matters in a derivative check. Nothing otherwise.
inline void rough_diffusion_field(flexipde::Scene &scene, Vec p, PetscReal lo, PetscReal hi) {
  const PetscInt kD = scene.params.find("advection_D");
  if (kD < 0 || scene.params.info(kD).kind != flexipde::ParamKind::Field) return;
  flexipde::OwnedVec f;
  PETSC_ASSERT_OK(DMCreateGlobalVector(scene.grid.dm(), f.out()));
  PETSC_ASSERT_OK(fill_random(f, lo, hi, 21));
  PETSC_ASSERT_OK(scene.params.set_field(p, kD, f));
}

using OptionList = std::vector<std::pair<const char *, const char *>>;

// A parameterised test's case that is a name and its options (suites that need nothing more share it),
// and gtest's test-name generator for any case with a `name`.
struct NamedOptions {
  const char *name;
  OptionList options;
};
inline std::ostream &operator<<(std::ostream &os, const NamedOptions &c) { return os << c.name; }
struct CaseName {
  template <class C>
  std::string operator()(const ::testing::TestParamInfo<C> &i) const {
    return i.param.name;
  }
};

// Data from p_true = 1.05 p, then the scene's value *J and gradient g at p.
inline void data_and_gradient(flexipde::Scene &scene, Vec p, flexipde::OwnedVec &p_true, flexipde::OwnedVec &g,
                              PetscReal *J) {
  PETSC_ASSERT_OK(scene.params.create_vec(p_true.out()));
  PETSC_ASSERT_OK(VecCopy(p, p_true));
  PETSC_ASSERT_OK(VecScale(p_true, 1.05));
  PETSC_ASSERT_OK(scene.make_synthetic_data(p_true));
  PETSC_ASSERT_OK(scene.params.create_vec(g.out()));
  PETSC_ASSERT_OK(scene.gradient(p, J, g));
}

inline void expect_gradients_match(PetscReal J1, PetscReal J0, Vec g1, Vec g0, PetscReal tol) {
  EXPECT_EQ(J1, J0);
  EXPECT_GT(norm(g0), 0.0);
  EXPECT_LT(rel_diff(g1, g0), tol);
}

// Two gradients of the scene at p, with data from 1.05 p: one with the options `on`, one with `on`
// and `alt` (e.g. a matrix-free path against the assembled one): the same J, gradients within tol
// (relative, max norm) of each other, and not zero.
inline void expect_same_gradient(flexipde::Scene &scene, Vec p, const OptionList &on, const OptionList &alt,
                                 PetscReal tol) {
  ScopedOptions base;
  for (auto &o : on) base.set(o.first, o.second);
  flexipde::OwnedVec p_true, g1, g0;
  PetscReal J1, J0;
  data_and_gradient(scene, p, p_true, g1, &J1);
  PETSC_ASSERT_OK(scene.params.create_vec(g0.out()));
  {
    ScopedOptions other;
    for (auto &o : alt) other.set(o.first, o.second);
    PETSC_ASSERT_OK(scene.gradient(p, &J0, g0));
  }
  expect_gradients_match(J1, J0, g1, g0, tol);
}

// Like expect_same_gradient, for a model option read only at set-up: the alternative gradient comes
// from a second Scene set up with `setup_alt` (and the same synthetic data, from p scaled by 1.05).
inline void expect_same_gradient_other_setup(flexipde::Scene &scene, Vec p, const OptionList &on,
                                             const OptionList &setup_alt, PetscReal tol) {
  ScopedOptions base;
  for (auto &o : on) base.set(o.first, o.second);
  flexipde::OwnedVec p_true, g1, g0;
  PetscReal J1, J0;
  data_and_gradient(scene, p, p_true, g1, &J1);
  flexipde::Scene other;
  {
    ScopedOptions alt;
    for (auto &o : setup_alt) alt.set(o.first, o.second);
    PETSC_ASSERT_OK(other.setup(PETSC_COMM_WORLD));
  }
  PETSC_ASSERT_OK(other.make_synthetic_data(p_true));
  PETSC_ASSERT_OK(other.params.create_vec(g0.out()));
  PETSC_ASSERT_OK(other.gradient(p, &J0, g0));
  expect_gradients_match(J1, J0, g1, g0, tol);
}

// dG/dp^T and the matrix-free J^T taken in any order, at one stage or at a new one, with y changed in
// between or not: Jp^T y always equals the product of the columns (dG/dp at the state of the last
// rhs_jacobian_p), and satisfies the dot-product identity with Jp. Returns, in *err, what applying Jp^T
// after U itself changed gives (0 when the model keeps its own copy of the state).
inline void check_fused_parameter_transpose(flexipde::Scene &scene, Mat Jmf, Mat Jp, Vec U, Vec p, PetscErrorCode *err) {
  using flexipde::OwnedVec;
  OwnedVec x, y, z, U2, g_cols, g_fused, Jx;
  for (auto *v : {&y, &z, &U2, &Jx}) PETSC_ASSERT_OK(VecDuplicate(U, v->out()));
  for (auto *v : {&x, &g_cols, &g_fused}) PETSC_ASSERT_OK(VecDuplicate(p, v->out()));
  PETSC_ASSERT_OK(fill_random(x, -1.0, 1.0, 29));
  PETSC_ASSERT_OK(fill_random(y, -1.0, 1.0, 30));
  PETSC_ASSERT_OK(fill_random(U2, -1.0, 1.0, 31));
  PETSC_ASSERT_OK(scene.model->rhs_jacobian_p(0.0, U, Jp));
  PETSC_ASSERT_OK(MatMultTranspose(Jp, y, g_cols));  // before any J^T: from the columns
  PETSC_ASSERT_OK(MatMultTranspose(Jmf, y, z));      // forms (dG/dp)^T y too
  PETSC_ASSERT_OK(MatMultTranspose(Jp, y, g_fused)); // takes it
  EXPECT_GT(norm(g_cols), 0.0);
  EXPECT_LT(rel_diff(g_fused, g_cols), 1e-13);
  PETSC_ASSERT_OK(MatMult(Jp, x, Jx)); // dot-product identity with the fused transpose
  EXPECT_LT(rel_diff(dot(Jx, y), dot(x, g_fused)), 1e-12);
  // y changed since J^T: differentiated again
  PETSC_ASSERT_OK(MatMultTranspose(Jmf, y, z));
  PETSC_ASSERT_OK(VecScale(y, 3.0));
  PETSC_ASSERT_OK(MatMultTranspose(Jp, y, g_fused));
  PETSC_ASSERT_OK(VecScale(g_cols, 3.0));
  EXPECT_LT(rel_diff(g_fused, g_cols), 1e-13);
  // a new stage after J^T: the product of the old one is not taken
  PETSC_ASSERT_OK(MatMultTranspose(Jmf, y, z));
  PETSC_ASSERT_OK(scene.model->rhs_jacobian_p(0.0, U2, Jp));
  PETSC_ASSERT_OK(MatMultTranspose(Jp, y, g_fused));
  PETSC_ASSERT_OK(MatMultTranspose(Jmf, y, z));
  PETSC_ASSERT_OK(MatMultTranspose(Jp, y, g_cols));
  EXPECT_LT(rel_diff(g_fused, g_cols), 1e-13);
  {
    OwnedVec g_ref;
    PETSC_ASSERT_OK(VecDuplicate(p, g_ref.out()));
    PETSC_ASSERT_OK(scene.model->rhs_jacobian_p(0.0, U, Jp));
    PETSC_ASSERT_OK(MatMultTranspose(Jp, y, g_ref));
    EXPECT_GT(rel_diff(g_fused, g_ref), 1e-3); // U2's, not U's
  }
  // new parameters after J^T: not taken either
  PETSC_ASSERT_OK(MatMultTranspose(Jmf, y, z));
  PETSC_ASSERT_OK(scene.model->set_parameters(p));
  PETSC_ASSERT_OK(scene.model->rhs_jacobian_p(0.0, U, Jp));
  PETSC_ASSERT_OK(MatMultTranspose(Jp, y, g_fused));
  PETSC_ASSERT_OK(MatMultTranspose(Jmf, y, z));
  PETSC_ASSERT_OK(MatMultTranspose(Jp, y, g_cols));
  EXPECT_LT(rel_diff(g_fused, g_cols), 1e-13);
  // the recorded state changed before dG/dp was formed there
  PETSC_ASSERT_OK(scene.model->rhs_jacobian_p(0.0, U, Jp));
  PETSC_ASSERT_OK(VecScale(U, 2.0));
  {
    QuietErrors quiet;
    *err = MatMultTranspose(Jp, y, g_fused);
  }
  if (!*err) EXPECT_LT(rel_diff(g_fused, g_cols), 1e-13);
}

// Every rank's copy, in a scene set up on PETSC_COMM_SELF, of the parameter Vec v of a distributed
// scene: scalars by value, fields through the grid's natural ordering (collective on the distributed
// scene's communicator).
inline PetscErrorCode to_serial_parameters(const flexipde::Scene &dist, Vec v, const flexipde::Scene &serial, Vec out) {
  using flexipde::OwnedVec;
  PetscFunctionBeginUser;
  for (PetscInt k = 0; k < dist.params.count(); ++k) {
    if (dist.params.info(k).kind == flexipde::ParamKind::Scalar) {
      PetscReal value;
      PetscCall(dist.params.scalar(v, k, &value));
      PetscCall(serial.params.set_scalar(out, k, value));
      continue;
    }
    if (dist.params.info(k).kind == flexipde::ParamKind::Vector) {
      std::vector<PetscReal> values;
      PetscCall(dist.params.vector_values(v, k, values));
      PetscCall(serial.params.set_vector(out, k, values));
      continue;
    }
    OwnedVec f, nat, fs;
    PetscCall(DMCreateGlobalVector(dist.grid.dm(), f.out()));
    PetscCall(dist.params.get_field(v, k, f));
    PetscCall(DMDACreateNaturalVector(dist.grid.dm(), nat.out()));
    PetscCall(DMDAGlobalToNaturalBegin(dist.grid.dm(), f, INSERT_VALUES, nat));
    PetscCall(DMDAGlobalToNaturalEnd(dist.grid.dm(), f, INSERT_VALUES, nat));
    std::vector<PetscReal> all;
    PetscCall(gather_all(nat, all));
    PetscCall(DMCreateGlobalVector(serial.grid.dm(), fs.out()));
    {
      PetscScalar *a;
      PetscInt n;
      PetscCall(VecGetLocalSize(fs, &n));
      PetscCheck(n == (PetscInt)all.size(), PETSC_COMM_SELF, PETSC_ERR_ARG_SIZ, "serial grid differs");
      PetscCall(VecGetArray(fs, &a));
      for (PetscInt i = 0; i < n; ++i) a[i] = all[i];
      PetscCall(VecRestoreArray(fs, &a));
    }
    PetscCall(serial.params.set_field(out, k, fs));
  }
  PetscFunctionReturn(0);
}

} // namespace flexipde_test
