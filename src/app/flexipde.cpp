// flexipde: run a scene from the options database.
//
//   -task forward   integrate to T and report ||U(T)||
//   -task gradient  J(p) and dJ/dp by TSAdjoint (-check_fd: compare one entry with central differences)
//   -task taylor    Taylor test of the gradient along a random direction (-taylor_eps, -taylor_levels)
//   -task landscape J(c) of a one-scalar scene at -landscape_n values in [-landscape_lower, -landscape_upper]
//   -task invert    synthetic data from the true parameters (-true_*), TAO from the initial ones,
//                   history and fields written to -output FILE.h5
//
// The seed FWI scene (n = 1000 on [0,1], dt = 5e-4, T = 2.5) is the default:
//   mpiexec -n 2 ./flexipde -task invert -wave_c 0.8 -true_wave_c 1.0 -tao_monitor
//   mpiexec -n 2 ./flexipde -task invert -wave_c_field 1 -true_wave_c_profile linear -true_wave_c_left 0.9 \
//           -wave_c_profile linear -wave_c_left 0.85 -inv_lower 0.5 -inv_upper 2 -output results/fwi_linear.h5
//   ./flexipde -help        lists every option of the chosen scene
//
// Timing (-task gradient): -timing_repeats N times N more forward solves and gradients in this process
// and prints their medians; with -timing_compare "OPTIONS" each repetition also times the same scene
// with OPTIONS added (in force during its own solves only; a second Scene set up with them), and
// prints the medians of the per-repetition ratios: on a machine whose speed changes from one minute to
// the next, two variants measured side by side in one process compare far better than two processes.
//   ./flexipde -task gradient -ts_type leapfrog -wave_c_field 1 -timing_repeats 21 -timing_compare adjoint_petsc_step=1
//   ./flexipde -task gradient -wave_c_field 1 -timing_repeats 11 -timing_compare ts_type=rk,ts_rk_type=4
#include <algorithm>
#include <cctype>
#include <cstdlib>
#include "flexipde/inversion.hpp"
#include "flexipde/io.hpp"
#include "flexipde/scene.hpp"
#include "flexipde/survey.hpp"
#include "flexipde/taylor.hpp"
#include <string>

using namespace flexipde;

static const char help[] = "flexipde: differentiable PDE simulation and inversion on PETSc.\n"
                           "  -task forward|gradient|taylor|invert   what to run\n"
                           "  -output FILE.h5                        results file (invert, forward)\n\n";

static PetscErrorCode write_parameters(H5Writer &w, const Scene &s, Vec p, const char *suffix) {
  OwnedVec f;
  PetscFunctionBeginUser;
  PetscCall(DMCreateGlobalVector(s.grid.dm(), f.out()));
  for (PetscInt k = 0; k < s.params.count(); ++k) {
    const ParamInfo &pi = s.params.info(k);
    std::string name = pi.name + "_" + suffix;
    if (pi.kind == ParamKind::Field) {
      PetscCall(s.params.get_field(p, k, f));
      PetscCall(w.write_vec("/fields", name.c_str(), f));
    } else if (pi.kind == ParamKind::Vector) {
      std::vector<PetscReal> v;
      PetscCall(s.params.vector_values(p, k, v));
      PetscCall(w.write_series("/vectors", name.c_str(), v));
    } else {
      PetscReal v;
      PetscCall(s.params.scalar(p, k, &v));
      PetscCall(w.write_series("/scalars", name.c_str(), {v}));
    }
  }
  PetscFunctionReturn(0);
}

static PetscErrorCode print_parameters(const Scene &s, Vec p, const char *label) {
  PetscFunctionBeginUser;
  for (PetscInt k = 0; k < s.params.count(); ++k) {
    const ParamInfo &pi = s.params.info(k);
    if (pi.kind == ParamKind::Scalar) {
      PetscReal v;
      PetscCall(s.params.scalar(p, k, &v));
      PetscCall(PetscPrintf(s.comm(), "%s %s = %.10f\n", label, pi.name.c_str(), (double)v));
    } else if (pi.kind == ParamKind::Vector && pi.entries <= 8) {
      std::vector<PetscReal> v;
      PetscCall(s.params.vector_values(p, k, v));
      PetscCall(PetscPrintf(s.comm(), "%s %s =", label, pi.name.c_str()));
      for (PetscReal x : v) PetscCall(PetscPrintf(s.comm(), " %.10f", (double)x));
      PetscCall(PetscPrintf(s.comm(), "\n"));
    }
  }
  PetscFunctionReturn(0);
}

static PetscErrorCode set_component_names(H5Writer &w, const Scene &scene) {
  std::vector<std::string> names;
  PetscFunctionBeginUser;
  for (PetscInt c = 0; c < scene.model->dof(); ++c) names.push_back(scene.model->component_name(c));
  w.set_component_names(names);
  PetscFunctionReturn(0);
}

// The options of -timing_compare, put in force and taken back around the alternative's solves: the
// values they replace are restored (cleared where there were none). Items separated by commas or
// spaces, each name=value (the leading '-' optional; on a command line a value cannot start with
// '-'), or PETSc's own form -name [value] (value: the next item unless it is a name itself).
class OptionSwap {
public:
  PetscErrorCode parse(MPI_Comm comm, const char *s) {
    std::vector<std::string> tok;
    std::string cur;
    PetscFunctionBeginUser;
    for (const char *c = s;; ++c) {
      if (*c == 0 || *c == ',' || std::isspace((unsigned char)*c)) {
        if (!cur.empty()) tok.push_back(cur);
        cur.clear();
        if (*c == 0) break;
      } else cur += *c;
    }
    auto is_name = [](const std::string &t) {
      if (t.size() < 2 || t[0] != '-') return false;
      char *end;
      std::strtod(t.c_str(), &end);
      return *end != 0; // "-1.5" is a value
    };
    for (size_t i = 0; i < tok.size(); ++i) {
      Entry e;
      const size_t eq = tok[i].find('=');
      if (eq != std::string::npos) {
        e.name = tok[i].substr(0, eq);
        if (e.name.empty() || e.name[0] != '-') e.name = "-" + e.name;
        e.value = tok[i].substr(eq + 1), e.has_value = true;
        PetscCheck(e.name.size() > 1, comm, PETSC_ERR_ARG_WRONG, "-timing_compare: no option name in \"%s\"", tok[i].c_str());
      } else {
        PetscCheck(is_name(tok[i]), comm, PETSC_ERR_ARG_WRONG,
                   "-timing_compare: expected name=value or -name [value], got \"%s\"", tok[i].c_str());
        e.name = tok[i];
        if (i + 1 < tok.size() && !is_name(tok[i + 1]) && tok[i + 1].find('=') == std::string::npos)
          e.value = tok[++i], e.has_value = true;
      }
      entries_.push_back(e);
    }
    PetscCheck(!entries_.empty(), comm, PETSC_ERR_ARG_WRONG, "-timing_compare: no options given");
    PetscFunctionReturn(0);
  }
  PetscErrorCode apply() {
    PetscFunctionBeginUser;
    for (Entry &e : entries_) {
      char v[PETSC_MAX_PATH_LEN] = "";
      PetscBool set;
      PetscCall(PetscOptionsGetString(nullptr, nullptr, e.name.c_str(), v, sizeof(v), &set));
      e.had = set, e.old = v;
      PetscCall(PetscOptionsSetValue(nullptr, e.name.c_str(), e.has_value ? e.value.c_str() : nullptr));
    }
    PetscFunctionReturn(0);
  }
  PetscErrorCode restore() {
    PetscFunctionBeginUser;
    for (const Entry &e : entries_) {
      if (e.had) PetscCall(PetscOptionsSetValue(nullptr, e.name.c_str(), e.old.empty() ? nullptr : e.old.c_str()));
      else PetscCall(PetscOptionsClearValue(nullptr, e.name.c_str()));
    }
    PetscFunctionReturn(0);
  }

private:
  struct Entry {
    std::string name, value, old;
    bool has_value = false, had = false;
  };
  std::vector<Entry> entries_;
};

static double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n == 0 ? 0.0 : n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

// One timed repetition: a forward solve and a gradient, with the gradient's two parts.
struct Timed {
  double forward, gradient, storing, adjoint;
};
static PetscErrorCode time_once(MPI_Comm comm, Scene &scene, Vec p, Vec U, Vec g, Timed *t) {
  PetscReal J;
  PetscFunctionBeginUser;
  PetscCallMPI(MPI_Barrier(comm));
  double t0 = MPI_Wtime();
  PetscCall(scene.sim.forward(p, U));
  PetscCallMPI(MPI_Barrier(comm));
  double t1 = MPI_Wtime();
  PetscCall(scene.gradient(p, &J, g));
  PetscCallMPI(MPI_Barrier(comm));
  *t = {t1 - t0, MPI_Wtime() - t1, scene.solver().stats().solve_seconds, scene.solver().stats().adjoint_seconds};
  PetscFunctionReturn(0);
}

// Medians of `repeats` forward solves and of `repeats` gradients (value + dJ/dp), timed in this
// process after a first gradient warmed everything up: no start-up, set-up or data generation. With
// `compare` (non-empty), each repetition also times a second Scene set up with those options added
// (synthetic data from the same p_true), right after the first.
static PetscErrorCode time_repeats(MPI_Comm comm, Scene &scene, Vec p, Vec p_true, PetscInt repeats, const char *compare) {
  OwnedVec U, g, gb, Ub;
  std::vector<Timed> a, b;
  Scene alt;
  OptionSwap swap;
  const bool cmp = compare && compare[0];
  PetscFunctionBeginUser;
  PetscCall(scene.sim.create_state(U.out()));
  PetscCall(VecDuplicate(p, g.out()));
  if (cmp) {
    PetscCall(swap.parse(comm, compare));
    PetscCall(swap.apply());
    PetscCall(alt.setup(comm));
    PetscCheck(alt.params.global_size() == scene.params.global_size(), comm, PETSC_ERR_ARG_INCOMP,
               "-timing_compare: with \"%s\" the scene has %" PetscInt_FMT " parameters, without %" PetscInt_FMT
               ": the two must take the same parameters",
               compare, alt.params.global_size(), scene.params.global_size());
    PetscCall(alt.make_synthetic_data(p_true));
    PetscCall(alt.sim.create_state(Ub.out()));
    PetscCall(VecDuplicate(p, gb.out()));
    PetscReal J;
    PetscCall(alt.gradient(p, &J, gb)); // warm-up, like the scene's own first gradient
    PetscCall(swap.restore());
  }
  for (PetscInt k = 0; k < repeats; ++k) {
    Timed t;
    PetscCall(time_once(comm, scene, p, U, g, &t));
    a.push_back(t);
    if (!cmp) continue;
    PetscCall(swap.apply());
    PetscCall(time_once(comm, alt, p, Ub, gb, &t));
    PetscCall(swap.restore());
    b.push_back(t);
  }
  auto col = [](const std::vector<Timed> &v, double Timed::*m) {
    std::vector<double> c;
    for (const Timed &t : v) c.push_back(t.*m);
    return c;
  };
  auto minimum = [](const std::vector<double> &v) { return *std::min_element(v.begin(), v.end()); };
  const double mf = median(col(a, &Timed::forward)), mg = median(col(a, &Timed::gradient));
  PetscCall(PetscPrintf(comm, "timing: %" PetscInt_FMT " repeats, forward median %.6f s (min %.6f), gradient median %.6f s (min %.6f), gradient/forward %.3f\n",
                        repeats, mf, minimum(col(a, &Timed::forward)), mg, minimum(col(a, &Timed::gradient)), mg / mf));
  PetscCall(PetscPrintf(comm, "timing: gradient parts (rank 0), medians: forward solve storing the trajectory %.6f s, adjoint solve %.6f s\n",
                        median(col(a, &Timed::storing)), median(col(a, &Timed::adjoint))));
  if (cmp) {
    std::vector<double> rf, rg, ra, rr;
    for (size_t k = 0; k < a.size(); ++k) {
      rf.push_back(b[k].forward / a[k].forward);
      rg.push_back(b[k].gradient / a[k].gradient);
      ra.push_back(b[k].adjoint / a[k].adjoint);
      rr.push_back((b[k].gradient / b[k].forward) / (a[k].gradient / a[k].forward));
    }
    PetscReal diff, nrm;
    PetscCall(VecNorm(g, NORM_INFINITY, &nrm));
    PetscCall(VecAXPY(gb, -1.0, g));
    PetscCall(VecNorm(gb, NORM_INFINITY, &diff));
    const double bf = median(col(b, &Timed::forward)), bg = median(col(b, &Timed::gradient));
    PetscCall(PetscPrintf(comm, "timing compare \"%s\": forward median %.6f s, gradient median %.6f s, gradient/forward %.3f; "
                                "storing %.6f s, adjoint %.6f s\n",
                          compare, bf, bg, bg / bf, median(col(b, &Timed::storing)), median(col(b, &Timed::adjoint))));
    PetscCall(PetscPrintf(comm, "timing compare: medians of the per-repetition ratios (with / without): forward %.4f, gradient %.4f "
                                "(%.4f-%.4f), adjoint %.4f, gradient/forward %.4f; gradients differ by %.3e (relative, max norm)\n",
                          median(rf), median(rg), *std::min_element(rg.begin(), rg.end()), *std::max_element(rg.begin(), rg.end()),
                          median(ra), median(rr), nrm > 0 ? (double)(diff / nrm) : (double)diff));
  }
  PetscFunctionReturn(0);
}

static PetscErrorCode run(MPI_Comm comm) {
  const char *tasks[] = {"forward", "gradient", "taylor", "invert", "landscape"};
  PetscInt task = 3, levels = 5;
  char output[PETSC_MAX_PATH_LEN] = "";
  PetscBool check_fd = PETSC_FALSE;
  PetscReal eps0 = 1e-2;
  PetscInt repeats = 0;
  char compare[PETSC_MAX_PATH_LEN] = "";
  PetscFunctionBeginUser;
  PetscOptionsBegin(comm, nullptr, "flexipde driver", "flexipde");
  PetscCall(PetscOptionsEList("-task", "What to run", "flexipde", tasks, 5, tasks[task], &task, nullptr));
  PetscCall(PetscOptionsString("-output", "HDF5 results file", "flexipde", output, output, sizeof(output), nullptr));
  PetscCall(PetscOptionsBool("-check_fd", "gradient: compare with central differences (scalars / first entry)",
                             "flexipde", check_fd, &check_fd, nullptr));
  PetscCall(PetscOptionsReal("-taylor_eps", "taylor: first step", "flexipde", eps0, &eps0, nullptr));
  PetscCall(PetscOptionsInt("-taylor_levels", "taylor: number of halvings", "flexipde", levels, &levels, nullptr));
  PetscCall(PetscOptionsInt("-timing_repeats", "gradient: time N more forward solves and N more gradients in this "
                            "process and print their medians (0: none)", "flexipde", repeats, &repeats, nullptr));
  PetscCall(PetscOptionsString("-timing_compare", "gradient with -timing_repeats: also time the scene with these options "
                               "added (name=value,name=value), alternating with it in this process, and print the "
                               "per-repetition ratios",
                               "flexipde", compare, compare, sizeof(compare), nullptr));
  PetscOptionsEnd();
  PetscCheck(repeats >= 0, comm, PETSC_ERR_ARG_OUTOFRANGE, "-timing_repeats must be non-negative");
  PetscCheck(!compare[0] || (task == 1 && repeats > 0), comm, PETSC_ERR_ARG_WRONG,
             "-timing_compare needs -task gradient and -timing_repeats N > 0");

  Scene scene;
  PetscCall(scene.setup(comm));
  OwnedVec p, p_true, g, U;
  PetscCall(scene.params.create_vec(p.out()));
  PetscCall(scene.params.create_vec(p_true.out()));
  PetscCall(scene.params.create_vec(g.out()));
  PetscCall(scene.sim.create_state(U.out()));
  PetscCall(scene.parameters_from_options("", p));
  PetscCall(scene.parameters_from_options("true_", p_true));
  PetscBool help = PETSC_FALSE;
  PetscCall(PetscOptionsHasHelp(nullptr, &help));
  if (help) { // list every option of this scene and stop before any work
    Inversion inv;
    PetscCall(scene.model->set_parameters(p));
    PetscCall(scene.sim.check_options());
    if (task == 3) PetscCall(inv.setup(scene, p_true));
    PetscFunctionReturn(0);
  }
  if (scene.grid.dim() == 3)
    PetscCall(PetscPrintf(comm,
                          "flexipde: model %s, %" PetscInt_FMT " x %" PetscInt_FMT " x %" PetscInt_FMT " points, %" PetscInt_FMT
                          " parameters\n",
                          scene.model->name(), scene.grid.n(), scene.grid.ny(), scene.grid.nz(), scene.params.global_size()));
  else if (scene.grid.dim() == 2)
    PetscCall(PetscPrintf(comm, "flexipde: model %s, %" PetscInt_FMT " x %" PetscInt_FMT " points, %" PetscInt_FMT " parameters\n",
                          scene.model->name(), scene.grid.n(), scene.grid.ny(), scene.params.global_size()));
  else
    PetscCall(PetscPrintf(comm, "flexipde: model %s, %" PetscInt_FMT " points, %" PetscInt_FMT " parameters\n",
                          scene.model->name(), scene.grid.n(), scene.params.global_size()));
  if (scene.shot_groups() > 1) {
    PetscMPIInt size;
    PetscCallMPI(MPI_Comm_size(comm, &size));
    PetscCall(PetscPrintf(comm, "shots: %" PetscInt_FMT " in %" PetscInt_FMT " groups of %d ranks\n",
                          scene.objective.survey()->shots(), scene.shot_groups(), size / (int)scene.shot_groups()));
  }

  if (task == 0) {
    PetscReal nrm;
    PetscCall(scene.sim.forward(p, U));
    PetscCall(VecNorm(U, NORM_2, &nrm));
    const SimulationStats &st = scene.sim.stats();
    PetscCall(PetscPrintf(comm, "forward: %s, %" PetscInt_FMT " steps of %g to T = %g, ||U(T)|| = %.12e\n", st.ts_type,
                          st.steps, (double)st.dt, (double)st.final_time, (double)nrm));
    if (output[0]) {
      H5Writer w;
      PetscCall(w.open(comm, output));
      PetscCall(w.write_coordinates(scene.grid));
      PetscCall(w.write_vec("/fields", "U_final", U));
      PetscCall(w.close());
    }
    PetscFunctionReturn(0);
  }

  PetscCall(scene.make_synthetic_data(p_true));
  if (task == 1) {
    PetscReal J, gn;
    PetscCall(scene.gradient(p, &J, g));
    PetscCall(VecNorm(g, NORM_2, &gn));
    PetscCall(PetscPrintf(comm, "gradient: J = %.12e, ||dJ/dp|| = %.12e (%s, %" PetscInt_FMT " steps)\n", (double)J,
                          (double)gn, scene.solver().stats().ts_type, scene.solver().stats().steps));
    const CheckpointStats &cs = scene.solver().checkpoint_stats();
    PetscCall(PetscPrintf(comm,
                          "checkpointing: budget %" PetscInt_FMT " (0: full storage), %" PetscInt_FMT
                          " states stored at most, %" PetscInt64_FMT " steps recomputed, binomial optimum %" PetscInt64_FMT "\n",
                          cs.budget, cs.stored_peak, cs.recomputed_steps, cs.optimal_recomputations));
    if (cs.memory_mb > 0)
      PetscCall(PetscPrintf(comm,
                            "checkpointing: -checkpoint_memory %.4g MB per rank, a state %.4g MB: %s (%" PetscInt_FMT
                            " steps)\n",
                            (double)cs.memory_mb, (double)cs.state_mb,
                            cs.budget ? "binomial schedule within it" : "every state fits, full storage", cs.steps));
    if (cs.stored_mb > 0)
      PetscCall(PetscPrintf(comm, "checkpointing: full storage held %.1f MB on rank 0\n", (double)cs.stored_mb));
    if (output[0]) {
      H5Writer w;
      PetscCall(w.open(comm, output));
      PetscCall(w.write_coordinates(scene.grid));
      PetscCall(w.write_vec("/gradient", "dJdp", g));
      PetscCall(w.write_series("/gradient", "J", std::vector<PetscReal>{J}));
      PetscCall(w.close());
    }
    if (repeats > 0) PetscCall(time_repeats(comm, scene, p, p_true, repeats, compare));
    if (check_fd) {
      const PetscReal h = 1e-6;
      OwnedVec q;
      PetscReal Jp, Jm;
      PetscCall(VecDuplicate(p, q.out()));
      PetscCall(VecCopy(p, q));
      PetscMPIInt rank;
      PetscCallMPI(MPI_Comm_rank(comm, &rank));
      if (rank == 0) PetscCall(VecSetValue(q, 0, h, ADD_VALUES)); // entry 0 once, not once per rank
      PetscCall(VecAssemblyBegin(q));
      PetscCall(VecAssemblyEnd(q));
      PetscCall(scene.value(q, &Jp));
      if (rank == 0) PetscCall(VecSetValue(q, 0, -2 * h, ADD_VALUES));
      PetscCall(VecAssemblyBegin(q));
      PetscCall(VecAssemblyEnd(q));
      PetscCall(scene.value(q, &Jm));
      PetscScalar g0 = 0;
      if (rank == 0) {
        ConstArray a(g);
        PetscCall(a.error());
        g0 = a[0];
      }
      PetscCallMPI(MPI_Bcast(&g0, 1, MPIU_SCALAR, 0, comm));
      const PetscReal fd = (Jp - Jm) / (2 * h), ad = PetscRealPart(g0);
      PetscCall(PetscPrintf(comm, "check_fd: adjoint dJ/dp_0 = %.12e, central difference = %.12e, relative difference = %.3e\n",
                            (double)ad, (double)fd, (double)(PetscAbsReal(ad - fd) / PetscMax(PetscAbsReal(fd), PETSC_SMALL))));
    }
    PetscFunctionReturn(0);
  }

  if (task == 4) {
    PetscInt n = 51;
    PetscReal lo = 0.5, hi = 1.5;
    PetscOptionsBegin(comm, nullptr, "Objective landscape", "flexipde");
    PetscCall(PetscOptionsInt("-landscape_n", "landscape: number of values", "flexipde", n, &n, nullptr));
    PetscCall(PetscOptionsReal("-landscape_lower", "landscape: first value", "flexipde", lo, &lo, nullptr));
    PetscCall(PetscOptionsReal("-landscape_upper", "landscape: last value", "flexipde", hi, &hi, nullptr));
    PetscOptionsEnd();
    PetscCheck(scene.params.global_size() == 1, comm, PETSC_ERR_ARG_WRONG,
               "-task landscape needs a scene with exactly one scalar parameter (e.g. -wave_c_field 0)");
    PetscCheck(n >= 2 && hi > lo, comm, PETSC_ERR_ARG_OUTOFRANGE, "-task landscape needs -landscape_n >= 2 and upper > lower");
    std::vector<PetscReal> cs, Js;
    for (PetscInt k = 0; k < n; ++k) {
      const PetscReal c = lo + (hi - lo) * k / (n - 1);
      PetscReal J;
      PetscCall(scene.params.set_scalar(p, 0, c));
      PetscCall(scene.value(p, &J)); // no adjoint; includes a time integral, if any
      cs.push_back(c);
      Js.push_back(J);
      PetscCall(PetscPrintf(comm, "landscape: %s = %.6f  J = %.10e\n", scene.params.info(0).name.c_str(), (double)c, (double)J));
    }
    if (output[0]) {
      H5Writer w;
      PetscCall(w.open(comm, output));
      PetscCall(w.write_series("/landscape", "parameter", cs));
      PetscCall(w.write_series("/landscape", "objective", Js));
      PetscCall(w.close());
    }
    PetscFunctionReturn(0);
  }

  if (task == 2) {
    OwnedVec d;
    PetscRandom rnd;
    TaylorResult tr;
    PetscCall(VecDuplicate(p, d.out()));
    PetscCall(PetscRandomCreate(comm, &rnd));
    PetscCall(PetscRandomSetInterval(rnd, -1.0, 1.0));
    PetscCall(VecSetRandom(d, rnd));
    PetscCall(PetscRandomDestroy(&rnd));
    auto f = [&](Vec q, PetscReal *J, Vec gq) { return scene.gradient(q, J, gq); };
    PetscCall(taylor_test(f, p, d, eps0, levels, tr));
    PetscCall(PetscPrintf(comm, "taylor: g.d = %.12e\n%12s %14s %8s %14s %8s\n", (double)tr.gd, "eps", "r1", "ratio", "r2",
                          "ratio"));
    for (size_t k = 0; k < tr.eps.size(); ++k)
      PetscCall(PetscPrintf(comm, "%12.4e %14.6e %8.3f %14.6e %8.3f\n", (double)tr.eps[k], (double)tr.r1[k],
                            k ? (double)tr.ratio1(k) : 0.0, (double)tr.r2[k], k ? (double)tr.ratio2(k) : 0.0));
    PetscFunctionReturn(0);
  }

  // invert
  Inversion inv;
  OwnedVec p0;
  PetscReal e0, e1;
  PetscCall(VecDuplicate(p, p0.out()));
  PetscCall(VecCopy(p, p0));
  PetscCall(inv.setup(scene, p_true));
  if (output[0]) inv.set_checkpoint_file(output); // rewritten every iteration (-inv_checkpoint_every): -inv_restart resumes from it
  PetscCall(inv.rmse(p, &e0));
  PetscCall(print_parameters(scene, p, "initial"));
  PetscCall(inv.solve(p));
  PetscCall(inv.rmse(p, &e1));
  const TaoConvergedReason reason = inv.converged_reason();
  const PetscInt its = inv.iterations();
  PetscCall(print_parameters(scene, p, "recovered"));
  PetscCall(PetscPrintf(comm, "invert: %s after %" PetscInt_FMT " iterations, %" PetscInt_FMT " gradient evaluations; parameter RMSE %.6e -> %.6e\n",
                        TaoConvergedReasons[reason], its, inv.evaluations(), (double)e0, (double)e1));
  if (output[0]) {
    H5Writer w;
    PetscCall(scene.sim.forward(p, U));
    PetscCall(w.open(comm, output));
    PetscCall(set_component_names(w, scene));
    PetscCall(w.write_coordinates(scene.grid));
    PetscCall(write_parameters(w, scene, p_true, "true"));
    PetscCall(write_parameters(w, scene, p0, "initial"));
    PetscCall(write_parameters(w, scene, p, "recovered"));
    PetscCall(w.write_vec("/fields", "U_final", U));
    if (scene.objective.data()) PetscCall(w.write_vec("/fields", "data", scene.objective.data()));
    PetscCall(inv.write_restart(w, p)); // /history and /restart
    PetscCall(w.close());
    PetscCall(PetscPrintf(comm, "invert: results written to %s\n", output));
  }
  PetscFunctionReturn(0);
}

int main(int argc, char **argv) {
  PetscCall(PetscInitialize(&argc, &argv, nullptr, help));
  // An error ends every rank at once with a non-zero exit (MPI_Abort), even if it was raised on
  // one rank only: no rank is left waiting in a collective call.
  PetscErrorCode ierr = run(PETSC_COMM_WORLD);
  if (ierr) MPI_Abort(MPI_COMM_WORLD, (int)ierr);
  { // a misspelled or unused option is reported (PETSc's -options_left decides when it is given)
    PetscBool set;
    PetscInt unused;
    PetscCall(PetscOptionsHasName(nullptr, nullptr, "-options_left", &set));
    PetscCall(PetscOptionsAllUsed(nullptr, &unused));
    if (!set && unused) {
      PetscCall(PetscPrintf(PETSC_COMM_WORLD, "WARNING: %" PetscInt_FMT " option(s) you set were not used (misspelled?):\n", unused));
      PetscCall(PetscOptionsLeft(nullptr));
    }
  }
  PetscCall(PetscFinalize());
  return 0;
}
