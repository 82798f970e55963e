#include "flexipde/model.hpp"

namespace flexipde {

std::unique_ptr<Model> make_advection_model();
std::unique_ptr<Model> make_wave_model();
std::unique_ptr<Model> make_vlasov_model();
std::unique_ptr<Model> make_wave2d_model();
std::unique_ptr<Model> make_vlasov_model();

std::map<std::string, ModelFactory> &model_registry() {
  static std::map<std::string, ModelFactory> registry = {
      {"advection", make_advection_model},
      {"wave", make_wave_model},
      {"vlasov", make_vlasov_model},
      {"wave2d", make_wave2d_model},
      {"vlasov", make_vlasov_model},
  };
  return registry;
}

std::string model_names() {
  std::string s;
  for (auto &kv : model_registry()) s += (s.empty() ? "" : ", ") + kv.first;
  return s;
}

PetscErrorCode create_model(MPI_Comm comm, const std::string &name, std::unique_ptr<Model> &model) {
  PetscFunctionBeginUser;
  auto it = model_registry().find(name);
  PetscCheck(it != model_registry().end(), comm, PETSC_ERR_ARG_UNKNOWN_TYPE, "Unknown model '%s': choose one of %s",
             name.c_str(), model_names().c_str());
  model = it->second();
  PetscFunctionReturn(0);
}

} // namespace flexipde
