// Objectives built on a model's named functional F(U) (Model::functional), e.g. the Vlasov field
// energy: at the final time, or integrated over time.
//   -objective_type functional           J = s F(U(T)),  or with -objective_target F*:
//                                        J = 0.5 (F(U(T)) / F* - 1)^2   (relative, so F's scale is irrelevant)
//   -objective_type functional_integral  J = s int_0^T F(U(t)) dt        (no terminal part)
// -objective_functional <name> picks F (default: the model's first), -objective_sign s is 1, or -1
// to maximise F with a minimiser. dJ/dU comes from the model's dF/dU; F does not depend on p.
#pragma once
#include "flexipde/model.hpp"
#include "flexipde/objective.hpp"
#include <string>

namespace flexipde {

class FunctionalObjective final : public Objective {
public:
  PetscErrorCode setup(MPI_Comm comm, Model &model, DM state_dm, bool integrated);
  PetscErrorCode terminal(Vec UT, PetscReal *J, Vec dJdU) override;
  bool has_integrand() const override { return integrated_; }
  PetscErrorCode integrand(PetscReal t, Vec U, PetscReal *r) override;
  PetscErrorCode integrand_dU(PetscReal t, Vec U, Vec drdU) override;
  const std::string &functional() const { return name_; }

private:
  Model *model_ = nullptr;
  bool integrated_ = false;
  std::string name_;
  PetscReal sign_ = 1, target_ = 0;
  PetscBool has_target_ = PETSC_FALSE;
};

} // namespace flexipde
