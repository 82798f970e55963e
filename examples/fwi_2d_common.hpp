// What the 2D and 3D inversion examples share (fwi_2d.cpp, fwi_marmousi.cpp, fwi_3d.cpp): their scenes
// given as option defaults that the command line overrides, speed fields made by code, and the results
// file (the true, initial and recovered speeds and the inversion's history) that run/plot_fwi_*.py read.
// The speed field is the model's "<model>_c" (wave2d_c, wave3d_c).
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

// "a,b,c": a list option's value.
inline std::string join(const std::vector<PetscReal> &v) {
  std::string s;
  for (PetscReal x : v) s += (s.empty() ? "" : ",") + std::to_string(x);
  return s;
}

using Speed2D = std::function<PetscReal(PetscReal, PetscReal)>;            // c(x, y)
using Speed3D = std::function<PetscReal(PetscReal, PetscReal, PetscReal)>; // c(x, y, z)

// The name of the scene's speed field: wave2d_c, wave3d_c.
inline std::string speed_name(const Scene &s) { return std::string(s.model->name()) + "_c"; }

// The speed field of p from c(x, y, z) (z = 0 on a 2D grid).
inline PetscErrorCode fill_speed(const Scene &s, Vec p, const Speed3D &c) {
  OwnedVec f;
  const Grid &g = s.grid;
  PetscFunctionBeginUser;
  PetscCall(DMCreateGlobalVector(g.dm(), f.out()));
  {
    Array a(f);
    PetscCall(a.error());
    // owned point q is ((k - zs) ym + (j - ys)) xm + (i - xs)
    for (PetscInt q = 0; q < g.local_points(); ++q)
      a[q] = c(g.x(g.xs() + q % g.xm()), g.y(g.ys() + (q / g.xm()) % g.ym()),
               g.dim() == 3 ? g.z(g.zs() + q / (g.xm() * g.ym())) : 0);
  }
  PetscCall(s.params.set_field(p, s.params.find(speed_name(s)), f));
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
  bool help = false; // -help: the scene's and the inversion's options were listed, nothing was run
  PetscErrorCode run(MPI_Comm comm, const Speed2D &truth, const Speed2D &initial) {
    PetscFunctionBeginUser;
    PetscCall(run(comm, Speed3D([&](PetscReal x, PetscReal y, PetscReal) { return truth(x, y); }),
                  Speed3D([&](PetscReal x, PetscReal y, PetscReal) { return initial(x, y); })));
    PetscFunctionReturn(0);
  }
  PetscErrorCode run(MPI_Comm comm, const Speed3D &truth, const Speed3D &initial) {
    PetscFunctionBeginUser;
    PetscCall(scene.setup(comm));
    PetscCall(scene.params.create_vec(p.out()));
    PetscCall(scene.params.create_vec(p_true.out()));
    PetscCall(scene.params.create_vec(p0.out()));
    PetscCall(fill_speed(scene, p_true, truth));
    PetscCall(fill_speed(scene, p, initial));
    PetscCall(VecCopy(p, p0));
    PetscBool listing;
    PetscCall(PetscOptionsHasHelp(nullptr, &listing));
    if (listing) { // list every option of the scene, its integrator and the inversion, and stop before any work
      help = true;
      PetscCall(scene.model->set_parameters(p));
      PetscCall(scene.sim.check_options());
      PetscCall(inv.setup(scene, p_true));
      PetscFunctionReturn(0);
    }
    PetscCall(scene.make_synthetic_data(p_true));
    PetscCall(inv.setup(scene, p_true));
    PetscCall(inv.rmse(p, &rmse_initial));
    PetscCall(inv.solve(p));
    PetscCall(inv.rmse(p, &rmse_recovered));
    PetscFunctionReturn(0);
  }
};

// /grid, /fields/<model>_c_{true,initial,recovered} and /history (iteration, objective, misfit, rmse)
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
  const std::string name = speed_name(s);
  const std::pair<Vec, std::string> fields[] = {{p_true, name + "_true"}, {p0, name + "_initial"}, {p, name + "_recovered"}};
  for (auto &fv : fields) {
    OwnedVec c;
    PetscCall(DMCreateGlobalVector(s.grid.dm(), c.out()));
    PetscCall(s.params.get_field(fv.first, s.params.find(name), c));
    PetscCall(w.write_vec("/fields", fv.second.c_str(), c));
  }
  PetscCall(w.write_series("/history", "iteration", it));
  PetscCall(w.write_series("/history", "objective", f));
  PetscCall(w.write_series("/history", "misfit", mis));
  PetscCall(w.write_series("/history", "rmse", rm));
  if (extra) PetscCall(extra(w));
  PetscCall(w.close());
  PetscFunctionReturn(0);
}

// An example's main(): PETSc around run(); an error on any rank ends every rank at once with a non-zero
// exit (MPI_Abort), so that none is left waiting in a collective call.
inline int main_of(int argc, char **argv, PetscErrorCode (*run)()) {
  PetscCall(PetscInitialize(&argc, &argv, nullptr, nullptr));
  PetscErrorCode ierr = run();
  if (ierr) MPI_Abort(MPI_COMM_WORLD, (int)ierr);
  PetscCall(PetscFinalize());
  return 0;
}

} // namespace fwi2d
