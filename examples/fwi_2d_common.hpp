// What the 2D inversion examples share (fwi_2d.cpp, fwi_marmousi.cpp): their scenes given as option
// defaults that the command line overrides, speed fields made by code, and the results file (the
// true, initial and recovered speeds and the inversion's history) that run/plot_fwi_*.py read.
#pragma once
#include "flexipde/inversion.hpp"
#include "flexipde/io.hpp"
#include "flexipde/scene.hpp"
#include <functional>
#include <string>
#include <utility>
#include <vector>

namespace fwi2d {
using namespace flexipde;

// Sets each option unless the user gave it.
inline PetscErrorCode default_options(const std::vector<std::pair<const char *, std::string>> &defaults) {
  PetscFunctionBeginUser;
  for (auto &d : defaults) {
    PetscBool set;
    PetscCall(PetscOptionsHasName(nullptr, nullptr, d.first, &set));
    if (!set) PetscCall(PetscOptionsSetValue(nullptr, d.first, d.second.c_str()));
  }
  PetscFunctionReturn(0);
}

// The speed field wave2d_c of p from c(x, y).
inline PetscErrorCode fill_speed(const Scene &s, Vec p, const std::function<PetscReal(PetscReal, PetscReal)> &c) {
  OwnedVec f;
  PetscFunctionBeginUser;
  PetscCall(DMCreateGlobalVector(s.grid.dm(), f.out()));
  {
    Array a(f);
    PetscCall(a.error());
    for (PetscInt k = 0; k < s.grid.local_points(); ++k)
      a[k] = c(s.grid.x(s.grid.xs() + k % s.grid.xm()), s.grid.y(s.grid.ys() + k / s.grid.xm()));
  }
  PetscCall(s.params.set_field(p, s.params.find("wave2d_c"), f));
  PetscFunctionReturn(0);
}

// The scene of the options, data from the true speed, and the inversion from the initial one: a scene set
// up from the options (grid, wave2d, survey, integrator, shot groups), the true and initial speed fields
// made by code, the synthetic traces of every shot (or -survey_data_file), and TAO through the
// Inversion (bounds, regularisation, frequency bands) with the history of misfit and RMSE.
struct Inverted {
  Scene scene;
  OwnedVec p, p_true, p0; // recovered, true and initial parameters
  Inversion inv;
  PetscReal rmse_initial = 0, rmse_recovered = 0;
  PetscErrorCode run(MPI_Comm comm, const std::function<PetscReal(PetscReal, PetscReal)> &truth,
                     const std::function<PetscReal(PetscReal, PetscReal)> &initial) {
    PetscFunctionBeginUser;
    PetscCall(scene.setup(comm));
    PetscCall(scene.params.create_vec(p.out()));
    PetscCall(scene.params.create_vec(p_true.out()));
    PetscCall(scene.params.create_vec(p0.out()));
    PetscCall(fill_speed(scene, p_true, truth));
    PetscCall(fill_speed(scene, p, initial));
    PetscCall(VecCopy(p, p0));
    PetscCall(scene.make_synthetic_data(p_true));
    PetscCall(inv.setup(scene, p_true));
    PetscCall(inv.rmse(p, &rmse_initial));
    PetscCall(inv.solve(p));
    PetscCall(inv.rmse(p, &rmse_recovered));
    PetscFunctionReturn(0);
  }
};

// /grid, /fields/wave2d_c_{true,initial,recovered} and /history (iteration, objective, misfit, rmse)
// into `file`; `extra` adds datasets of its own to the open file.
inline PetscErrorCode write_results(const char *file, const Scene &s, Vec p_true, Vec p0, Vec p, const Inversion &inv,
                                    const std::function<PetscErrorCode(H5Writer &)> &extra = nullptr) {
  H5Writer w;
  std::vector<PetscReal> it, f, mis, rm;
  PetscFunctionBeginUser;
  for (auto &h : inv.history()) {
    it.push_back(h.iteration);
    f.push_back(h.objective);
    mis.push_back(h.misfit);
    rm.push_back(h.rmse);
  }
  PetscCall(w.open(s.comm(), file));
  PetscCall(w.write_coordinates(s.grid));
  const std::pair<Vec, const char *> fields[] = {{p_true, "wave2d_c_true"}, {p0, "wave2d_c_initial"}, {p, "wave2d_c_recovered"}};
  for (auto &fv : fields) {
    OwnedVec c;
    PetscCall(DMCreateGlobalVector(s.grid.dm(), c.out()));
    PetscCall(s.params.get_field(fv.first, s.params.find("wave2d_c"), c));
    PetscCall(w.write_vec("/fields", fv.second, c));
  }
  PetscCall(w.write_series("/history", "iteration", it));
  PetscCall(w.write_series("/history", "objective", f));
  PetscCall(w.write_series("/history", "misfit", mis));
  PetscCall(w.write_series("/history", "rmse", rm));
  if (extra) PetscCall(extra(w));
  PetscCall(w.close());
  PetscFunctionReturn(0);
}

} // namespace fwi2d
