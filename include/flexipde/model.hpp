// The interface between a PDE and the integrators: dU/dt = G(t, U; p) on a grid.
//
// A model provides its components per grid point, G, dG/dU (an assembled Mat or a MatShell with
// MultTranspose), dG/dp for the parameters it declares, and its initial condition U0(p) with the
// transpose of dU0/dp. It never sees the adjoint, the trajectory, the optimiser or the output:
// the Simulation owns those and works for every model alike. A new model does not implement this
// class by hand: it states G and U0 at one grid point and PointwiseModel (pointwise.hpp) derives all
// of it (docs/adding_a_model.md).
#pragma once
#include "flexipde/grid.hpp"
#include "flexipde/parameters.hpp"
#include <complex>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

namespace flexipde {

struct PointSource;       // survey.hpp
class LeapfrogStepParts;  // leapfrog.hpp
class LeapfrogSplitParts; // leapfrog.hpp

// Bounds on the spectrum of dG/dU, used to refuse explicit steps beyond the stability limit.
struct Spectrum {
  PetscReal imag_radius = 0; // eigenvalues have |Im| <= imag_radius
  PetscReal real_radius = 0; // and -real_radius <= Re <= 0
  // Optional, and then used instead of the two radii: the eigenvalues themselves (e.g. the symbol
  // of a periodic constant-coefficient operator at every mode), or points of the boundary of a set
  // known to hold them. The Simulation checks |R(dt lambda)| <= 1 at each.
  std::vector<std::complex<PetscReal>> samples;
};

class Model {
public:
  virtual ~Model() = default;
  virtual const char *name() const = 0;
  virtual PetscInt dof() const = 0;
  virtual const char *component_name(PetscInt c) const = 0;
  // Ghost width the model's stencils need (the grid is created with it).
  virtual PetscInt stencil_width(MPI_Comm comm) const = 0;
  // Dimension of the model's grid (1, or 2 for 2D space or 1D1V phase space), and the grid
  // defaults the model prefers (bounds, periodicity); options override them.
  virtual PetscInt dim() const { return 1; }
  virtual void grid_defaults(GridOptions &) const {}

  // Reads the model's options and declares its parameters (before params.finalize()).
  virtual PetscErrorCode setup(const Grid &grid, DM state_dm, Parameters &params) = 0;
  // Called once the parameter layout is final, before any solve.
  virtual PetscErrorCode create_jacobian(Mat *J) = 0;
  virtual PetscErrorCode create_jacobian_p(Mat *Jp) = 0;
  // Optional: dG/dU as a matrix-free operator (a MatShell with Mult and MultTranspose, always at the
  // current parameters) for explicit integrators, which only apply it; implicit ones factor the
  // assembled one. *J = null when the model has none.
  virtual PetscErrorCode create_jacobian_matrix_free(Mat *J) {
    *J = nullptr;
    return 0;
  }

  // Tell the model the current parameter values (before each solve).
  virtual PetscErrorCode set_parameters(Vec p) = 0;
  virtual PetscErrorCode rhs(PetscReal t, Vec U, Vec G) = 0;
  virtual PetscErrorCode rhs_jacobian(PetscReal t, Vec U, Mat J) = 0;
  virtual PetscErrorCode rhs_jacobian_p(PetscReal t, Vec U, Mat Jp) = 0;
  // True when G is linear in U (lets an implicit integrator skip Newton).
  virtual bool linear() const { return false; }
  // True when dG/dU depends on neither t nor U (only on p): the Simulation then assembles it
  // once per parameter value instead of once per stage.
  virtual bool jacobian_constant() const { return false; }
  virtual PetscErrorCode spectrum(Spectrum *s) = 0;
  // Second-order-in-time structure, for the leapfrog (Stormer-Verlet) integrator: m > 0 when
  // components 0..m-1 are positions q and m..2m-1 their velocities p, with G_q = p exactly and
  // G_p = a(t, q; p) - sigma(x) p: a damping sigma >= 0 that depends on neither the state nor the
  // parameters (an absorbing sponge), else no p. 0 when the model has no such form.
  virtual PetscInt second_order_pairs() const { return 0; }
  // Optional, for second-order models: the leapfrog adjoint's work at one time level fused into one
  // sweep without any matrix, on the adjoint's positions and velocities in arrays of their own (lambda_q,
  // lambda_p: m per owned point each, laid out like the positions): at state U, first
  // lambda_p += drift lambda_q at every point (the transpose of the drift that ends at this level;
  // drift = 0: none), then
  //   lambda_q += w (dG_p/dq)^T lambda_p   and, unless mu is null,   mu += w (dG_p/dtheta)^T lambda_p
  // (both updated in place). A model may fold the drift into its sweep or apply it first
  // (leapfrog_drift_transpose). U is a whole state or the positions q alone (m contiguous components
  // per grid point, laid out like the grid's own one-component Vecs for m = 1; G_p reads nothing
  // else): a full-storage trajectory hands the kick the stored positions in place. `prefetch` (null:
  // none) is where the next call's stored positions are (as many as U's positions): the model should
  // prefetch them, best spread over its sweep. Without this the integrator uses rhs_jacobian and
  // rhs_jacobian_p with their transposes and its own drift pass: the same numbers in more passes.
  virtual bool has_second_order_adjoint() const { return false; }
  virtual PetscErrorCode second_order_adjoint(PetscReal t, Vec U, Vec lambda_q, Vec lambda_p, PetscReal w, Vec mu,
                                              PetscReal drift, const PetscScalar *prefetch) {
    (void)t, (void)U, (void)lambda_p, (void)w, (void)mu, (void)drift, (void)prefetch;
    SETERRQ(PetscObjectComm((PetscObject)lambda_q), PETSC_ERR_SUP, "Model %s has no fused second-order adjoint", name());
  }
  // Optional, for second-order models: a whole leapfrog step in one sweep over the grid. accel = G_p(t, U)
  // (m per owned point, the velocity rows of G) at the state after parts.kick_drift, which must reach
  // every owned point before G reads its positions (on any rank), and parts.kick on every point once
  // its G is final; collective. Without it the integrator makes three passes (kick and drift, G,
  // kick): the same numbers.
  virtual bool has_second_order_step() const { return false; }
  virtual PetscErrorCode second_order_step(PetscReal t, Vec U, PetscScalar *accel, const LeapfrogStepParts &parts) {
    (void)t, (void)accel, (void)parts;
    SETERRQ(PetscObjectComm((PetscObject)U), PETSC_ERR_SUP, "Model %s has no fused leapfrog step", name());
  }
  // With second_order_step: the leapfrog's split step on the positions Q (m per owned point, the layout of
  // a grid DM with m components; changed in place) and the velocities v (m per owned point): parts.point_kick
  // on every point with a = G_p at t and the positions (the velocities read as 0: G_p's damping is the
  // integrator's) once the point's a is final, and parts.drift on every point once no G reads its
  // positions (on any rank); collective.
  virtual PetscErrorCode second_order_split_step(PetscReal t, Vec Q, PetscScalar *v, const LeapfrogSplitParts &parts) {
    (void)t, (void)v, (void)parts;
    SETERRQ(PetscObjectComm((PetscObject)Q), PETSC_ERR_SUP, "Model %s has no leapfrog split step", name());
  }
  // Optional: the products of one explicit-RK adjoint stage fused into one sweep without any matrix:
  // at state U,
  //   y = (dG/dU)^T x   and, unless mu is null,   mu += (dG/dtheta)^T x.
  // Without it the RK adjoint is PETSc's TSAdjointStep_RK, which applies rhs_jacobian's and
  // rhs_jacobian_p's transposes: the same numbers, in more passes.
  virtual bool has_stage_adjoint() const { return false; }
  // Stage records: r = stage_record_size() > 0 when evaluating G at a state computes, on the way, r local
  // numbers that stage_adjoint at that state would otherwise compute again (the wave models: L u; Vlasov:
  // the field E(f) at the owned x). rhs_record() is rhs() that also writes them to `record`. Full storage
  // keeps them for every stage (the RHS evaluations at the stages write them in place) and
  // stage_adjoint receives them; when stage_record_replaces_state() it needs nothing else of the stage
  // (U is null then) and full storage keeps only the records, which are then the stage's positions
  // (second_order_pairs() per point; a cost integrand that reads them alone works from them too). Without a record (null: the stage was
  // recomputed) stage_adjoint works from U.
  virtual PetscInt stage_record_size() const { return 0; }
  virtual bool stage_record_replaces_state() const { return false; }
  virtual PetscErrorCode rhs_record(PetscReal t, Vec U, Vec G, PetscScalar *record) {
    (void)record;
    return rhs(t, U, G);
  }
  virtual PetscErrorCode stage_adjoint(PetscReal t, Vec U, const PetscScalar *record, Vec x, Vec y, Vec mu) {
    (void)t, (void)record, (void)x, (void)y, (void)mu;
    SETERRQ(PetscObjectComm((PetscObject)x), PETSC_ERR_SUP, "Model %s has no fused RK adjoint stage", name());
  }
  // Optional, around one adjoint solve (the Simulation calls begin_adjoint() before TSAdjointSolve and
  // end_adjoint(mu) after it, also when the solve fails: mu null then): in between, the transposes of
  // dG/dtheta (rhs_jacobian_p's MatMultTranspose, stage_adjoint) may leave out a final linear map that
  // every one of their contributions to mu shares (e.g. the projection a field parameter goes through),
  // for end_adjoint to apply to mu once. Outside, they apply it themselves.
  virtual void begin_adjoint() {}
  virtual PetscErrorCode end_adjoint(Vec mu) {
    (void)mu;
    return 0;
  }
  // Point sources (survey.hpp): a model that takes them adds the source's forcing density to G (the
  // wave: to v_t) from then on; null removes it. The forcing depends on t only, never on U or p.
  virtual bool accepts_point_source() const { return false; }
  virtual PetscErrorCode set_point_source(const PointSource *) { return 0; }

  // Named scalar functionals F(U) of the state (e.g. an energy), for objectives and diagnostics
  // (collective): F into *value, and dF/dU into dFdU unless it is null. functional_names() lists
  // the names a model accepts ("" when none); any other name is an error.
  virtual std::string functional_names() const { return ""; }
  virtual PetscErrorCode functional(const char *fname, Vec U, PetscReal *value, Vec dFdU) {
    (void)value, (void)dFdU;
    SETERRQ(PetscObjectComm((PetscObject)U), PETSC_ERR_ARG_WRONG, "Model %s has no functional '%s'%s%s", name(), fname,
            functional_names().empty() ? "" : ": choose one of ", functional_names().c_str());
  }

  // The fixed step dt the integrator will take, given before every initial_condition by the
  // Simulation: for initial conditions defined through the scheme's first step (the wave's two-level
  // start). Most models ignore it.
  virtual void set_time_step(PetscReal dt) { (void)dt; }
  // U0 = U0(p), and grad += (dU0/dp)^T lambda0, at the parameters set last by set_parameters(p) (the
  // Simulation sets them first: Simulation::initial_condition).
  virtual PetscErrorCode initial_condition(Vec p, Vec U0) = 0;
  virtual PetscErrorCode initial_condition_transpose(Vec p, Vec lambda0, Vec grad) = 0;
};

using ModelFactory = std::function<std::unique_ptr<Model>()>;
std::map<std::string, ModelFactory> &model_registry();
// Registration: one line at the end of a model's file makes `-model NAME` create it.
struct ModelRegistration {
  ModelRegistration(const char *name, ModelFactory factory);
};
#define FLEXIPDE_REGISTRATION_ID2(L) flexipde_model_registration_##L
#define FLEXIPDE_REGISTRATION_ID(L) FLEXIPDE_REGISTRATION_ID2(L)
#define FLEXIPDE_REGISTER_MODEL(NAME, TYPE)                                                                            \
  static const ::flexipde::ModelRegistration FLEXIPDE_REGISTRATION_ID(__LINE__)(                                        \
      NAME, [] { return std::unique_ptr<::flexipde::Model>(new TYPE()); })

PetscErrorCode create_model(MPI_Comm comm, const std::string &name, std::unique_ptr<Model> &model);
std::string model_names();

} // namespace flexipde
